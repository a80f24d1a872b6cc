"""McapFileWriter: an MCAP file written by a thread of its own, fed without blocking the loop.

The loop only appends (robot, kind, log time, payload) to a bounded deque: no file call,
no serialisation, no lock. The thread drains it every ``FLUSH_INTERVAL`` seconds, in
slices of ``SLICE`` seconds with a ``PAUSE`` after each (it shares the GIL with the loop),
serialises the statuses and events, and writes through ``mcap.writer.Writer`` (its
defaults: zstd chunks of 1 MiB, chunk and message indexes, statistics and the summary). A
chunk is also finished every ``CHUNK_SECONDS``, so a file cut short (a crash, a power cut)
is readable up to its last chunk. When ``max_queued`` messages wait, later ones are dropped
and counted, never waited for.
"""

from __future__ import annotations

import collections
import json
import logging
import threading
import time
from typing import IO, Any

from ..errors import InvalidArgument
from ..events import Event
from ..models import GalileoStatus
from ..sim.mcap_read import topic
from .schemas import (
    LOG_SCHEMA,
    LOG_SCHEMA_NAME,
    STATUS_SCHEMA_NAME,
    event_log,
    status_json,
    status_schema,
)

__all__ = [
    "CHUNK_SECONDS",
    "DEFAULT_CHUNK_SIZE",
    "DEFAULT_MAX_QUEUED",
    "FLUSH_INTERVAL",
    "McapFileWriter",
]

_log = logging.getLogger(__name__)

#: Seconds between two drains of the queue by the writer thread.
FLUSH_INTERVAL = 0.05
#: Seconds of wall time after which the chunk in progress is finished and flushed.
CHUNK_SECONDS = 5.0
#: Messages waiting for the thread at most (a second of 1000 robots' frames, about).
DEFAULT_MAX_QUEUED = 100_000
#: Longest the thread works without a pause (it holds the GIL meanwhile) …
SLICE = 0.001
#: … and its pause after each slice (the loop holds the GIL alone): a quarter of a core.
PAUSE = 0.003
#: Compact JSON, no check for circles (the values are plain).
_ENCODER = json.JSONEncoder(separators=(",", ":"), check_circular=False)
#: Bytes of messages per chunk (the mcap writer's default).
DEFAULT_CHUNK_SIZE = 1024 * 1024
#: The raw channel's message encoding: the serial protocol's bytes, as read.
RAW_ENCODING = "galileo.serial"

_RAW, _STATUS, _EVENT, _ADD = 0, 1, 2, 3
_KIND_NAMES = ("raw", "status", "events")


def _writer_module() -> Any:
    try:
        from mcap import writer
    except ImportError:
        raise InvalidArgument(
            "MCAP recordings need the mcap package: pip install 'galileo-async[mcap]'"
        ) from None
    return writer


class McapFileWriter:
    """Writes one MCAP file from its own thread; ``add_*`` are called on the loop only."""

    def __init__(
        self,
        stream: IO[bytes],
        *,
        max_queued: int = DEFAULT_MAX_QUEUED,
        chunk_size: int = DEFAULT_CHUNK_SIZE,
    ) -> None:
        self._mcap = _writer_module().Writer(stream, chunk_size=chunk_size)
        self._stream = stream
        self._queue: collections.deque[tuple[int, str, int, Any]] = collections.deque()
        self._max_queued = max_queued
        self._stopping = threading.Event()
        self._thread = threading.Thread(target=self._run, name="mcap writer", daemon=False)
        #: Messages not written because the thread fell ``max_queued`` behind, by kind.
        self.dropped = {"raw": 0, "status": 0, "events": 0}
        #: Messages written, by kind (read once the writer is closed).
        self.written = {"raw": 0, "status": 0, "events": 0}
        #: The error that ended the thread early (the disk full …), else None.
        self.error: BaseException | None = None
        self._channels: dict[tuple[str, int], int] = {}
        #: The schema ids of the raw (none), status and events channels.
        self._schemas = (0, 0, 0)

    def start(self) -> None:
        """Start the thread (it writes the header first)."""
        self._thread.start()

    def add_robot(self, robot: str, raw: bool) -> None:
        """Register ``robot``'s channels (raw only when its link carries bytes); never dropped."""
        self._queue.append((_ADD, robot, 0, raw))

    def add(self, kind: int, robot: str, log_time: int, payload: Any) -> None:
        """Queue a message, or count it dropped when the thread is ``max_queued`` behind."""
        queue = self._queue
        if len(queue) >= self._max_queued or self.error is not None:
            self.dropped[_KIND_NAMES[kind]] += 1
            return
        queue.append((kind, robot, log_time, payload))

    def add_raw(self, robot: str, log_time: int, data: bytes) -> None:
        """Queue the bytes of one read."""
        self.add(_RAW, robot, log_time, data)

    def add_status(self, robot: str, log_time: int, status: GalileoStatus) -> None:
        """Queue one status (serialised by the thread)."""
        self.add(_STATUS, robot, log_time, status)

    def add_event(self, robot: str, log_time: int, event: Event) -> None:
        """Queue one event (serialised by the thread)."""
        self.add(_EVENT, robot, log_time, event)

    def stop(self) -> None:
        """Ask the thread to write what is queued, finish the file and end (returns at once)."""
        self._stopping.set()

    def join(self, timeout: float | None = None) -> bool:
        """Wait for the thread (in a thread, never on the loop); True once it ended."""
        self._thread.join(timeout)
        return not self._thread.is_alive()

    @property
    def alive(self) -> bool:
        """True while the thread runs."""
        return self._thread.is_alive()

    # --- the thread --------------------------------------------------------------------

    def _run(self) -> None:
        try:
            self._mcap.start(profile="", library="galileo_async")
            status_id = self._mcap.register_schema(
                STATUS_SCHEMA_NAME, "jsonschema", json.dumps(status_schema()).encode()
            )
            log_id = self._mcap.register_schema(
                LOG_SCHEMA_NAME, "jsonschema", json.dumps(LOG_SCHEMA).encode()
            )
            self._schemas = (0, status_id, log_id)
            chunk_started = time.monotonic()
            main = threading.main_thread()
            while True:
                # A program that ends without closing its recorder still gets a whole file.
                stopping = self._stopping.wait(FLUSH_INTERVAL) or not main.is_alive()
                self._drain()
                if stopping:
                    break
                if time.monotonic() - chunk_started >= CHUNK_SECONDS:
                    self._mcap.flush()
                    chunk_started = time.monotonic()
            self._drain()
            self._mcap.finish()
        except BaseException as exc:
            self.error = exc
            _log.error("the MCAP recording failed: %s", exc)
        finally:
            try:
                self._stream.close()
            except OSError as exc:
                self.error = self.error or exc

    def _drain(self) -> None:
        """Write everything queued, in slices of SLICE seconds with a PAUSE between them."""
        queue, mcap, channels = self._queue, self._mcap, self._channels
        dumps = _ENCODER.encode
        clock = time.perf_counter
        slice_ends = clock() + SLICE
        count = 0
        while queue:
            count += 1
            if not count % 8 and clock() > slice_ends:
                # Asleep, the thread does not wait for the GIL: the loop's every system
                # call would hand it over otherwise, and the loop wait for it each time.
                time.sleep(PAUSE)
                slice_ends = clock() + SLICE
            kind, robot, log_time, payload = queue.popleft()
            if kind == _ADD:
                self._register(robot, payload)
                continue
            if kind == _RAW:
                data = payload
            elif kind == _STATUS:
                data = dumps(status_json(payload)).encode()
            else:
                data = dumps(event_log(payload, log_time, robot)).encode()
            channel = channels.get((robot, kind))
            if channel is None:
                continue  # a robot's channel that was never registered (raw on udp://)
            mcap.add_message(channel, log_time=log_time, data=data, publish_time=log_time)
            self.written[_KIND_NAMES[kind]] += 1

    def _register(self, robot: str, raw: bool) -> None:
        _none, status_id, log_id = self._schemas
        if raw:
            self._channels[(robot, _RAW)] = self._mcap.register_channel(
                topic(robot, "raw"), RAW_ENCODING, 0, {"robot": robot}
            )
        self._channels[(robot, _STATUS)] = self._mcap.register_channel(
            topic(robot, "status"), "json", status_id, {"robot": robot}
        )
        self._channels[(robot, _EVENT)] = self._mcap.register_channel(
            topic(robot, "events"), "json", log_id, {"robot": robot}
        )
