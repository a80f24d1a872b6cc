"""McapRecorder: one robot or a whole fleet recorded into one MCAP file, off the loop."""

from __future__ import annotations

import asyncio
import logging
import time
from collections.abc import Callable
from pathlib import Path
from types import TracebackType
from typing import IO

from .._checks import check_int
from ..errors import InvalidArgument
from ..events import Event
from ..fleet import Fleet
from ..models import GalileoStatus
from ..robot import Robot
from ..robot.runtime import finish_shielded
from .writer import DEFAULT_CHUNK_SIZE, DEFAULT_MAX_QUEUED, McapFileWriter

__all__ = ["DEFAULT_ROBOT_NAME", "McapRecorder"]

_log = logging.getLogger(__name__)

#: The name of a single Robot's channels (``/robot/raw`` …) unless told otherwise.
DEFAULT_ROBOT_NAME = "robot"


class _Attached:
    """One robot's listeners, removed on close."""

    def __init__(self, robot: Robot, name: str, recorder: McapRecorder) -> None:
        self.robot = robot
        writer, stamp = recorder._writer, recorder._stamp

        def on_raw(data: bytes) -> None:
            writer.add_raw(name, stamp(), data)

        def on_status(status: GalileoStatus) -> None:
            writer.add_status(name, stamp(), status)

        def on_event(event: Event) -> None:
            writer.add_event(name, stamp(), event)

        self.on_raw: Callable[[bytes], None] = on_raw
        self.on_status: Callable[[GalileoStatus], None] = on_status
        self.on_event: Callable[[Event], None] = on_event
        raw = robot.add_raw_listener(on_raw)
        writer.add_robot(name, raw)
        robot.add_update_listener(on_status)
        robot.add_event_listener(on_event)

    def detach(self) -> None:
        self.robot.remove_raw_listener(self.on_raw)
        self.robot.remove_update_listener(self.on_status)
        self.robot.remove_event_listener(self.on_event)


def _close_opened(opening: asyncio.Future[IO[bytes]]) -> None:
    """Close the file a cancelled start opened."""
    if not opening.cancelled() and opening.exception() is None:
        opening.result().close()


class McapRecorder:
    """``async with McapRecorder("run.mcap", robot_or_fleet):`` records until the block ends.

    Per robot (a Robot's ``name``, a Fleet's robot names; a fleet robot is recorded from
    when it connects): ``/<name>/raw`` the bytes as they came off the link (serial,
    socket://, sim:// only), ``/<name>/status`` every status as JSON and
    ``/<name>/events`` every event as a foxglove.Log; log times are the loop clock's,
    anchored to the wall clock at the start. The loop never waits for the disk: the
    listeners only queue, a task builds the records in slices of a millisecond, and a
    worker thread writes them. When it falls ``max_queued`` messages behind, later
    messages are dropped and counted (``dropped``), never waited for. A chunk is finished every
    ``chunk_size`` bytes of messages and every few seconds, so a file cut short is read up
    to its last chunk. On every exit (an error, a cancellation) the file is finished: its
    summary and indexes written.
    """

    def __init__(
        self,
        path: str | Path,
        source: Robot | Fleet,
        *,
        name: str = DEFAULT_ROBOT_NAME,
        max_queued: int = DEFAULT_MAX_QUEUED,
        chunk_size: int = DEFAULT_CHUNK_SIZE,
    ) -> None:
        if not isinstance(source, (Robot, Fleet)):
            raise InvalidArgument(f"McapRecorder records a Robot or a Fleet, got {source!r}")
        if not isinstance(name, str) or not name or "/" in name:
            raise InvalidArgument(f"name must be a non-empty name without '/', got {name!r}")
        check_int("max_queued", max_queued, 1, 10_000_000)
        check_int("chunk_size", chunk_size, 1, 1 << 30)
        self._chunk_size = chunk_size
        self.path = Path(path)
        self._source = source
        self._name = name
        self._max_queued = max_queued
        self._writer: McapFileWriter
        self._attached: dict[str, _Attached] = {}
        self._fleet: Fleet | None = None
        self._stamp: Callable[[], int] = time.time_ns
        self._finishing: asyncio.Task[None] | None = None
        self._started = False

    @property
    def dropped(self) -> int:
        """Messages not recorded because the disk could not keep up."""
        return sum(self._writer.dropped.values()) if self._started else 0

    @property
    def dropped_by_kind(self) -> dict[str, int]:
        """``dropped`` by channel kind: raw, status, events."""
        return dict(self._writer.dropped) if self._started else {}

    @property
    def written(self) -> dict[str, int]:
        """Messages written, by channel kind (complete once the recorder closed)."""
        return dict(self._writer.written) if self._started else {}

    @property
    def robots(self) -> tuple[str, ...]:
        """The robots being recorded (a fleet's, once connected)."""
        return tuple(self._attached)

    async def start(self) -> None:
        """Open the file (off the loop) and start recording."""
        if self._started:
            raise InvalidArgument("this McapRecorder was started already")
        loop = asyncio.get_running_loop()
        try:
            # Shielded: a start cancelled while the thread opens the file closes it after.
            opening: asyncio.Future[IO[bytes]] = asyncio.ensure_future(
                asyncio.to_thread(self.path.open, "wb")
            )
            try:
                stream: IO[bytes] = await asyncio.shield(opening)
            except asyncio.CancelledError:
                opening.add_done_callback(_close_opened)
                raise
        except OSError as exc:
            raise InvalidArgument(f"cannot write {self.path}: {exc.strerror or exc}") from None
        try:
            self._writer = McapFileWriter(
                stream, max_queued=self._max_queued, chunk_size=self._chunk_size
            )
        except BaseException:
            stream.close()
            raise
        epoch, began = time.time_ns(), loop.time()
        self._stamp = lambda: epoch + int((loop.time() - began) * 1e9)
        self._writer.start()
        self._started = True
        source = self._source
        if isinstance(source, Robot):
            self._attach(self._name, source)
        else:
            self._fleet = source
            source.add_connect_listener(self._on_connect, connected=True)

    def _attach(self, name: str, robot: Robot) -> None:
        self._attached[name] = _Attached(robot, name, self)

    def _on_connect(self, name: str, robot: Robot) -> None:
        """A fleet robot (connected now, or later): recorded from then on."""
        if self._finishing is None and name not in self._attached:
            self._attach(name, robot)

    async def aclose(self) -> None:
        """Stop recording and finish the file: idempotent, shielded from cancellation and
        bounded (the caller's cancellation is raised once the file is finished)."""
        if not self._started:
            return
        if self._finishing is None:
            if self._fleet is not None:
                self._fleet.remove_connect_listener(self._on_connect)
            for attached in self._attached.values():
                attached.detach()
            self._finishing = asyncio.get_running_loop().create_task(
                self._finish(), name="mcap finish"
            )
        await finish_shielded(self._finishing, f"finishing the recording {self.path}")
        if self._writer.error is not None:
            raise OSError(f"recording to {self.path} failed: {self._writer.error}")

    async def _finish(self) -> None:
        await self._writer.finish()
        if self.dropped:
            _log.warning(
                "the disk could not keep up: %d messages were not recorded to %s (%s)",
                self.dropped, self.path, self.dropped_by_kind,
            )  # fmt: skip

    async def __aenter__(self) -> McapRecorder:
        await self.start()
        return self

    async def __aexit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        await self.aclose()
