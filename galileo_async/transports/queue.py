"""CommandQueue: the FIFO in front of a link's one paced writer (room, supersession, failure)."""

from __future__ import annotations

import asyncio
import logging
from collections import deque
from typing import Any

from ..errors import GalileoConnectionError
from ..protocol import Command

__all__ = ["CommandQueue", "Pending"]

_log = logging.getLogger(__name__)

#: One queued command and the future its sender waits on (True: written, False: dropped).
Pending = tuple[Command, "asyncio.Future[bool]"]
#: A queued command that a later command of one of these types drops (CommandQueue.enqueue).
_Supersedable = tuple[Pending, tuple[type[Command], ...]]


class CommandQueue:
    """The queue half of BaseLink: the writer pops ``_queue[0]``; everything else is here."""

    __slots__ = ()

    _queue: deque[Pending]
    _queue_ready: asyncio.Event
    _room_waiters: deque[asyncio.Future[None]]
    _supersedable: list[_Supersedable]
    max_queued_commands: int

    def _check_can_send(self) -> None:
        """Raise ConnectionLost unless the link can take a command now."""
        raise NotImplementedError

    def enqueue(
        self,
        command: Command,
        *,
        superseded_by: tuple[type[Command], ...] = (),
        written: asyncio.Future[bool] | None = None,
    ) -> asyncio.Future[bool]:
        """Queue ``command`` now, behind every earlier command and ahead of every later one.

        Synchronous, so a cancellation handler can queue a command before it awaits
        anything; it does not wait for room (max_queued_commands), so only callers that
        queue a bounded number of commands use it. The future is True once the command is
        written, False when it was dropped because a command of a type in
        ``superseded_by`` was queued after it first; cancelling it unqueues the command.
        Raises ConnectionLost while the link is closed or down. ``written``: use this future
        (see send) instead of a new one.
        """
        self._check_can_send()
        future = asyncio.get_running_loop().create_future() if written is None else written
        entry = (command, future)
        if self._supersedable:
            self._supersede(type(command))
        self._queue.append(entry)
        if superseded_by:
            self._supersedable.append((entry, superseded_by))
        self._queue_ready.set()
        return future

    async def send(self, command: Command, *, written: asyncio.Future[bool] | None = None) -> Any:
        """Queue one command for the paced writer (waiting while full); once written, its answer.

        The answer is what the link got back for the command (an ApiCall's JSON); None
        where commands get none.

        ``written``, if given, is the future the writer resolves: the caller may fail it
        (or cancel it) to withdraw the command; as long as that happens before its turn,
        synchronously, the command is never written and send raises that failure.
        """
        self._check_can_send()
        if self._room_waiters or len(self._queue) >= self.max_queued_commands:
            await self._wait_for_room()
        if written is not None and written.done():
            self._make_room()  # withdrawn while waiting for room: hand the place on
            await written  # raises its failure
        future = self.enqueue(command, written=written)
        try:
            await future
        finally:
            if future.done() and (future.cancelled() or future.exception() is not None):
                self._unqueue(future)  # not written: free its place now
        return None

    def _supersede(self, kind: type[Command]) -> None:
        """Drop the queued commands that a command of type ``kind`` supersedes."""
        keep: list[_Supersedable] = []
        for entry, superseded_by in self._supersedable:
            future = entry[1]
            if future.done():
                continue
            if issubclass(kind, superseded_by):
                _log.debug("%s dropped: superseded by a later %s", entry[0], kind.__name__)
                future.set_result(False)
                self._unqueue(future)
            else:
                keep.append((entry, superseded_by))
        self._supersedable[:] = keep

    def _unqueue(self, future: asyncio.Future[bool]) -> None:
        """Remove the queued command of ``future`` (if still queued) and hand its place on."""
        for index, (_, queued) in enumerate(self._queue):
            if queued is future:
                del self._queue[index]
                break
        self._make_room()

    async def _wait_for_room(self) -> None:
        """Wait, first come first served, for a place in the full queue."""
        waiter: asyncio.Future[None] = asyncio.get_running_loop().create_future()
        self._room_waiters.append(waiter)
        try:
            await waiter
            self._check_can_send()  # the link may have dropped meanwhile
        except BaseException:
            self._room_waiters.remove(waiter)
            self._make_room()  # hand the place this sender will not use to the next one
            raise
        self._room_waiters.remove(waiter)

    def _make_room(self) -> None:
        room = self.max_queued_commands - len(self._queue)
        for waiter in self._room_waiters:
            if room <= 0:
                return
            if not waiter.done():
                waiter.set_result(None)
            room -= 1  # woken but not yet running: the place is taken

    def _fail_pending(self, exc: GalileoConnectionError) -> None:
        pending = list(self._queue)
        self._queue.clear()  # in place: the writer holds a reference to this deque
        self._supersedable.clear()
        for _, future in pending:
            if not future.done():
                future.set_exception(exc)
        self._make_room()
