"""The commands of a Link: the FIFO (room, supersession, failure) and its one paced writer."""

from __future__ import annotations

import asyncio
import logging
from collections import deque
from collections.abc import Callable
from typing import Any

from ..errors import CommandSuperseded, ConnectionLost, GalileoConnectionError, GalileoError
from ..protocol import Command
from . import options as _options
from .channel import Channel
from .stats import LinkStats

__all__ = ["CommandQueue", "PacedWriter", "Pending"]

_log = logging.getLogger(__name__)


class Pending:
    """One queued command, the future its sender waits on, and the channel's answer."""

    __slots__ = ("answer", "command", "future")

    def __init__(self, command: Command, future: asyncio.Future[bool]) -> None:
        self.command = command
        #: True once written, False when superseded; cancelling it unqueues the command.
        self.future = future
        #: What the channel's write returned (set before ``future`` resolves True).
        self.answer: Any = None


class CommandQueue:
    """Commands waiting for the writer, in order; the writer pops ``entries[0]``."""

    __slots__ = (
        "_check", "_room_waiters", "_supersedable", "entries", "max_queued", "ready", "stats",
    )  # fmt: skip

    def __init__(self, max_queued: int, check: Callable[[], None], stats: LinkStats) -> None:
        """``check``: raises (ConnectionLost) unless the link can take a command now.

        ``stats.commands_superseded`` counts the commands dropped here unwritten because a
        later command or a user stop superseded them.
        """
        self.max_queued = max_queued
        self._check = check
        self.stats = stats
        self.entries: deque[Pending] = deque()
        #: Set when there is something for the writer.
        self.ready = asyncio.Event()
        self._room_waiters: deque[asyncio.Future[None]] = deque()
        self._supersedable: list[tuple[Pending, tuple[type[Command], ...]]] = []

    def enqueue(
        self,
        command: Command,
        *,
        superseded_by: tuple[type[Command], ...] = (),
        written: asyncio.Future[bool] | None = None,
    ) -> Pending:
        """Queue ``command`` now, behind every earlier one (no wait for room); its entry."""
        self._check()
        future = asyncio.get_running_loop().create_future() if written is None else written
        entry = Pending(command, future)
        if self._supersedable:
            self._supersede(type(command))
        self.entries.append(entry)
        if superseded_by:
            self._supersedable.append((entry, superseded_by))
        self.ready.set()
        return entry

    async def send(self, command: Command, *, written: asyncio.Future[bool] | None) -> Any:
        """Queue one command (waiting while full); its answer once written.

        ``written``: a future the caller may fail or cancel to withdraw the command before
        its turn; send then raises that failure.
        """
        self._check()
        if self._room_waiters or len(self.entries) >= self.max_queued:
            await self._wait_for_room()
        if written is not None and written.done():
            self.make_room()  # withdrawn while waiting for room: hand the place on
            self._count_if_superseded(written)
            await written  # raises its failure
        entry = self.enqueue(command, written=written)
        future = entry.future
        try:
            await future
        finally:
            if future.done() and (future.cancelled() or future.exception() is not None):
                self.unqueue(future)  # not written: free its place now
                self._count_if_superseded(future)
        return entry.answer

    def _count_if_superseded(self, future: asyncio.Future[bool]) -> None:
        """Count ``future``'s command as superseded if a user stop withdrew it."""
        if not future.cancelled() and isinstance(future.exception(), CommandSuperseded):
            self.stats.commands_superseded += 1

    def _supersede(self, kind: type[Command]) -> None:
        """Drop the queued commands that a command of type ``kind`` supersedes."""
        keep: list[tuple[Pending, tuple[type[Command], ...]]] = []
        for entry, superseded_by in self._supersedable:
            future = entry.future
            if future.done():
                continue
            if issubclass(kind, superseded_by):
                _log.debug("%s dropped: superseded by a later %s", entry.command, kind.__name__)
                future.set_result(False)
                self.unqueue(future)
                self.stats.commands_superseded += 1
            else:
                keep.append((entry, superseded_by))
        self._supersedable[:] = keep

    def unqueue(self, future: asyncio.Future[bool]) -> None:
        """Remove the queued command of ``future`` (if still queued) and hand its place on."""
        for index, entry in enumerate(self.entries):
            if entry.future is future:
                del self.entries[index]
                break
        self.make_room()

    async def _wait_for_room(self) -> None:
        """Wait, first come first served, for a place in the full queue."""
        waiter: asyncio.Future[None] = asyncio.get_running_loop().create_future()
        self._room_waiters.append(waiter)
        try:
            await waiter
            self._check()  # the link may have dropped meanwhile
        except BaseException:
            self._room_waiters.remove(waiter)
            self.make_room()  # hand the place this sender will not use to the next one
            raise
        self._room_waiters.remove(waiter)

    def make_room(self) -> None:
        """Wake as many room waiters as there are free places."""
        room = self.max_queued - len(self.entries)
        for waiter in self._room_waiters:
            if room <= 0:
                return
            if not waiter.done():
                waiter.set_result(None)
            room -= 1  # woken but not yet running: the place is taken

    def fail(self, exc: GalileoConnectionError) -> None:
        """Fail every queued command with ``exc`` and empty the queue."""
        pending = list(self.entries)
        self.entries.clear()  # in place: the writer holds a reference to this deque
        self._supersedable.clear()
        for entry in pending:
            if not entry.future.done():
                entry.future.set_exception(exc)
        self.make_room()


class PacedWriter:
    """The one writer of a link: FIFO, paced, one command per write, into an empty buffer."""

    __slots__ = ("channel", "drain_timeout", "last_write", "min_command_interval", "queue", "stats")

    def __init__(
        self,
        queue: CommandQueue,
        channel: Channel,
        stats: LinkStats,
        min_command_interval: float,
        drain_timeout: float,
    ) -> None:
        self.queue = queue
        self.channel = channel
        self.stats = stats
        #: Least time between two writes.
        self.min_command_interval = min_command_interval
        #: Longest the transport may hold unsent bytes before the queued sends fail.
        self.drain_timeout = drain_timeout
        #: When the last command was written (the link's clock), None before the first.
        self.last_write: float | None = None

    async def run(self) -> None:
        """Write the queue's commands until cancelled (the Link's writer task)."""
        entries = self.queue.entries
        ready = self.queue.ready
        channel = self.channel
        stalled_since: float | None = None
        while True:
            if not entries or not self.stats.transport_open:
                stalled_since = None
                ready.clear()
                await ready.wait()
                continue
            entry = entries[0]
            future = entry.future
            if future.done():  # its sender was cancelled before the write
                entries.popleft()
                self.queue.make_room()
                continue
            now = self.stats.clock()
            if self.last_write is not None:
                wait = self.last_write + self.min_command_interval - now
                if wait > 0:
                    await asyncio.sleep(wait)
                    continue
            # A stalled transport flushes what it buffered back to back in one segment, and
            # the firmware loses commands written back to back (docs/protocol.md §2): write only
            # into an empty buffer.
            buffered = channel.pending_bytes()
            if buffered:
                if stalled_since is None:
                    stalled_since = now
                elif now - stalled_since >= self.drain_timeout:
                    stalled_since = None
                    self.queue.fail(
                        GalileoConnectionError(
                            f"not sent: the transport still holds {buffered} unsent bytes "
                            f"after {self.drain_timeout} s (the peer does not read)"
                        )
                    )
                    continue
                await asyncio.sleep(_options.DRAIN_POLL_INTERVAL)
                continue
            stalled_since = None
            entries.popleft()
            self.queue.make_room()
            await self._write(entry)

    async def _write(self, entry: Pending) -> None:
        """Write one popped entry through the channel and settle its future."""
        command, future = entry.command, entry.future
        try:
            answer = await self.channel.write(command)
        except asyncio.CancelledError:
            if not future.done():
                future.set_exception(ConnectionLost("the link is closed"))
            raise
        except GalileoError as exc:  # the channel's own errors reach the sender as they are
            if not future.done():
                future.set_exception(exc)
            return
        except Exception as exc:  # a broken transport must not kill the only writer
            _log.exception("writing %s failed", command)
            error = GalileoConnectionError(f"writing {command} failed: {exc!r}")
            error.__cause__ = exc
            if not future.done():
                future.set_exception(error)
            return
        self.last_write = self.stats.clock()
        self.stats.commands_sent += 1
        entry.answer = answer
        if not future.done():
            future.set_result(True)
