"""McapFileWriter: an MCAP file fed without blocking the loop; the disk written off it.

The listeners only append (robot, kind, log time, payload) to a bounded deque: no file
call, no serialisation. A task on the loop (the pump) drains it every ``FLUSH_INTERVAL``
seconds in slices of at most ``SLICE`` seconds with a pause after each, longer while the
loop is busy, so it never holds the loop longer than a slice nor takes more than half of
it: it serialises the statuses and events and builds the records with
``mcap.writer.Writer`` (its defaults but for the chunk size: zstd chunks, chunk and
message indexes, statistics and the summary) into memory; the finished bytes go to the
file through one worker thread of its own, where the write does not hold the GIL. A
thread doing the serialising was measured and dropped: sharing the GIL with the loop, it
made the loop wait up to the interpreter's switch interval at each of its system calls
(BENCHMARKS.md, "MCAP recordings"). A chunk is finished every ``chunk_size`` bytes and
every ``CHUNK_SECONDS``, so a file cut short is readable up to its last chunk. When
``max_queued`` messages wait, later ones are dropped and counted, never waited for.
"""

from __future__ import annotations

import asyncio
import collections
import concurrent.futures
import contextlib
import json
import logging
import time
from collections.abc import Callable
from typing import IO, Any

from ..errors import InvalidArgument
from ..events import Event
from ..models import GalileoStatus
from ..schemas import (
    LOG_SCHEMA,
    LOG_SCHEMA_NAME,
    STATUS_SCHEMA_NAME,
    event_log,
    status_json,
    status_schema,
)
from ..sim.mcap_read import topic

__all__ = [
    "CHUNK_SECONDS",
    "DEFAULT_CHUNK_SIZE",
    "DEFAULT_MAX_QUEUED",
    "FLUSH_INTERVAL",
    "McapFileWriter",
]

_log = logging.getLogger(__name__)

#: Seconds between two drains of the queue.
FLUSH_INTERVAL = 0.05
#: Longest the pump holds the loop at a time …
SLICE = 0.001
#: … and the pause after a slice that left messages, at least (at most half the loop) …
PAUSE = 0.001
#: … and at most, while the loop is busy with other work (the recorder drops, then).
MAX_PAUSE = 0.032
#: Seconds after which the chunk in progress is finished and written.
CHUNK_SECONDS = 5.0
#: Messages waiting at most: a third of a second of 1000 robots, a backlog a busy loop
#: still finishes within the close's 8 s.
DEFAULT_MAX_QUEUED = 20_000
#: Bytes of messages per chunk: small enough to compress within a slice or so.
DEFAULT_CHUNK_SIZE = 128 * 1024
#: The raw channel's message encoding: the serial protocol's bytes, as read.
RAW_ENCODING = "galileo.serial"
#: Compact JSON, no check for circles (the values are plain).
_ENCODER = json.JSONEncoder(separators=(",", ":"), check_circular=False)

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


class _Pending:
    """What the mcap writer wrote, held until the pump hands it to the file."""

    def __init__(self) -> None:
        self.parts: list[bytes] = []
        self.position = 0

    def write(self, data: bytes) -> int:
        self.parts.append(bytes(data))
        self.position += len(data)
        return len(data)

    def tell(self) -> int:
        return self.position

    def flush(self) -> None:
        return None

    def take(self) -> bytes:
        data, self.parts = b"".join(self.parts), []
        return data


class McapFileWriter:
    """Writes one MCAP file to ``stream``; every method is called on the loop."""

    def __init__(
        self,
        stream: IO[bytes],
        *,
        max_queued: int = DEFAULT_MAX_QUEUED,
        chunk_size: int = DEFAULT_CHUNK_SIZE,
    ) -> None:
        self._pending = _Pending()
        self._mcap = _writer_module().Writer(self._pending, chunk_size=chunk_size)
        self._stream = stream
        self._queue: collections.deque[tuple[int, str, int, Any]] = collections.deque()
        self._max_queued = max_queued
        self._stopping = False
        self._pump: asyncio.Task[None] | None = None
        self._pause = PAUSE
        self._finished = False
        #: One worker, so that the file's writes keep their order, even on the way out.
        self._disk = concurrent.futures.ThreadPoolExecutor(1, thread_name_prefix="mcap file")
        #: Messages not written because the pump fell ``max_queued`` behind, by kind.
        self.dropped = {"raw": 0, "status": 0, "events": 0}
        #: Messages written, by kind.
        self.written = {"raw": 0, "status": 0, "events": 0}
        #: The error that ended the recording early (the disk full …), else None.
        self.error: BaseException | None = None
        self._channels: dict[tuple[str, int], int] = {}
        self._mcap.start(profile="", library="galileo_async")
        self._status_schema = self._mcap.register_schema(
            STATUS_SCHEMA_NAME, "jsonschema", json.dumps(status_schema()).encode()
        )
        self._log_schema = self._mcap.register_schema(
            LOG_SCHEMA_NAME, "jsonschema", json.dumps(LOG_SCHEMA).encode()
        )

    def start(self) -> None:
        """Start the pump on the running loop."""
        self._pump = asyncio.get_running_loop().create_task(self._run(), name="mcap writer")

    def add_robot(self, robot: str, raw: bool) -> None:
        """Register ``robot``'s channels (raw only when its link carries bytes); never dropped."""
        self._queue.append((_ADD, robot, 0, raw))

    def add(self, kind: int, robot: str, log_time: int, payload: Any) -> None:
        """Queue a message, or count it dropped when the pump is ``max_queued`` behind."""
        queue = self._queue
        if len(queue) >= self._max_queued or self.error is not None or self._stopping:
            self.dropped[_KIND_NAMES[kind]] += 1
            return
        queue.append((kind, robot, log_time, payload))

    def add_raw(self, robot: str, log_time: int, data: bytes) -> None:
        """Queue the bytes of one read."""
        self.add(_RAW, robot, log_time, data)

    def add_status(self, robot: str, log_time: int, status: GalileoStatus) -> None:
        """Queue one status (serialised by the pump)."""
        self.add(_STATUS, robot, log_time, status)

    def add_event(self, robot: str, log_time: int, event: Event) -> None:
        """Queue one event (serialised by the pump)."""
        self.add(_EVENT, robot, log_time, event)

    async def finish(self) -> None:
        """Write what is queued, finish the file and close it (once; later calls wait)."""
        self._stopping = True
        if self._pump is not None:
            await asyncio.wait([self._pump])  # its end, not a cancellation of its own

    # --- the pump ------------------------------------------------------------------------

    async def _run(self) -> None:
        loop = asyncio.get_running_loop()
        chunk_started = loop.time()
        try:
            while True:
                stopping = self._stopping
                await self._drain()
                if loop.time() - chunk_started >= CHUNK_SECONDS:
                    self._mcap.flush()
                    chunk_started = loop.time()
                await self._write_out()
                if stopping:
                    break
                await asyncio.sleep(FLUSH_INTERVAL)
            self._mcap.finish()
            self._finished = True
            await self._write_out()
            await self._on_disk(self._stream.close)
        except asyncio.CancelledError:
            # The loop is going away with the recording open: finish it here and now.
            self._finish_blocking()
            raise
        except Exception as exc:
            self.error = exc
            _log.error("the MCAP recording failed: %s", exc)
            with contextlib.suppress(OSError):
                await self._on_disk(self._stream.close)  # off the loop: a disk may hang
        finally:
            self._disk.shutdown(wait=False)

    async def _on_disk(self, call: Callable[..., object], *args: object) -> None:
        await asyncio.get_running_loop().run_in_executor(self._disk, call, *args)

    async def _write_out(self) -> None:
        data = self._pending.take()
        if data:
            await self._on_disk(self._stream.write, data)

    def _finish_blocking(self) -> None:
        """Finish the file on this thread, after the writes already handed to the disk."""
        try:
            if not self._finished:
                self._drain_slice(None, len(self._queue))
                self._mcap.finish()
                self._finished = True
            if data := self._pending.take():
                self._disk.submit(self._stream.write, data).result()
        except Exception as exc:
            self.error = exc
        finally:
            self._disk.submit(self._stream.close).result()

    async def _drain(self) -> None:
        """Write what is queued now, in slices of SLICE seconds with a pause after each.

        The pause grows (to MAX_PAUSE) while the loop comes back late from it, a loop with
        other work, and shrinks back to PAUSE once it does not: the loop comes first.
        """
        left, pause, clock = len(self._queue), self._pause, time.perf_counter
        while left > 0:
            left = self._drain_slice(clock() + SLICE, left)
            if left > 0:
                began = clock()
                await asyncio.sleep(pause)
                late = clock() - began - pause
                pause = min(MAX_PAUSE, pause * 2) if late > SLICE else max(PAUSE, pause / 2)
        self._pause = pause

    def _drain_slice(self, until: float | None, most: int) -> int:
        """Build at most ``most`` queued messages' records until ``until``; how many of the
        ``most`` are left."""
        queue, mcap, channels, written = self._queue, self._mcap, self._channels, self.written
        dumps, clock = _ENCODER.encode, time.perf_counter
        count = 0
        while queue and count < most:
            count += 1
            if until is not None and not count % 8 and clock() > until:
                return most - count + 1
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
            written[_KIND_NAMES[kind]] += 1
        return 0 if not queue else most - count

    def _register(self, robot: str, raw: bool) -> None:
        if raw:
            self._channels[(robot, _RAW)] = self._mcap.register_channel(
                topic(robot, "raw"), RAW_ENCODING, 0, {"robot": robot}
            )
        self._channels[(robot, _STATUS)] = self._mcap.register_channel(
            topic(robot, "status"), "json", self._status_schema, {"robot": robot}
        )
        self._channels[(robot, _EVENT)] = self._mcap.register_channel(
            topic(robot, "events"), "json", self._log_schema, {"robot": robot}
        )
