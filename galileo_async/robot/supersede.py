"""What a user stop reaches: the drive or goal commands still waiting, the drive session,
the calls awaiting motion, and the sends that must finish though their caller was cancelled."""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Callable, Coroutine
from typing import Any, Protocol, TypeVar

from ..errors import CommandSuperseded, GalileoError, GoalCancelled

__all__ = ["DriveSlot", "Supersession", "goal_superseded"]

_R = TypeVar("_R")
_log = logging.getLogger(__name__)


class _Session(Protocol):
    """What a user stop uses of a DriveSession."""

    @property
    def active(self) -> bool:
        """True while its block runs and no user stop ended it."""

    @property
    def stop_written(self) -> asyncio.Future[bool] | None:
        """The write of its one stop, once queued."""

    def end(self, by: str | None = None) -> GalileoError | None:
        """End it now and queue its one stop."""


class DriveSlot:
    """The one drive session a Robot may have at a time."""

    __slots__ = ("session",)

    def __init__(self) -> None:
        self.session: _Session | None = None

    @property
    def active(self) -> bool:
        """True while a session's block runs and no user stop ended it."""
        return self.session is not None and self.session.active

    def end(self, by: str = "close()") -> asyncio.Future[bool] | None:
        """End the session now (``by`` the user stop that did), its one stop queued; its future."""
        session = self.session
        if session is None:
            return None
        session.end(by)
        return session.stop_written


class Supersession:
    """The user's stops of one Robot and what they reach; Operations holds one and applies it."""

    def __init__(self) -> None:
        #: Bumped synchronously (before any await) by every user stop: Robot.stop(), cancel(),
        #: pause(), stop_navigation(), close(). A drive or goal command called before the bump
        #: and not yet written is never written.
        self.stops = 0
        self._stopped_by = ""
        # The write futures of the waiting drive and goal commands, with their sends' names.
        self._withdrawable: dict[asyncio.Future[bool], str] = {}
        #: Sends that must finish though their caller was cancelled (exit cancels, stop());
        #: held here so that they do, and close() awaits them.
        self.held: set[asyncio.Future[Any]] = set()
        # How to end each call that awaits motion now (goto, rotate_to …), with the id of the
        # HTTP task it follows, if any; keyed by a token.
        self._motions: dict[object, tuple[Callable[[str], None], str | None]] = {}
        #: The drive session inside whose block the caller is, if any; a user stop ends it.
        self.drive = DriveSlot()
        #: Called with the stop's name after every user stop (Robot.add_stop_listener).
        self.stop_listeners: list[Callable[[str], None]] = []

    @property
    def stopped_by(self) -> str:
        """The latest user stop's name ("stop()", "cancel()" …), or "a user stop" before one."""
        return self._stopped_by or "a user stop"

    def user_stopped(self, what: str) -> None:
        """A user stop (``what``, e.g. "stop()"): supersede each waiting drive/goal, end the drive.

        Synchronous: a withdrawn command's write future fails now, so the link's writer, which
        skips a command whose future is done, can never write it, even in this loop turn; the
        drive session's one stop is queued after that.
        """
        self.stops += 1
        self._stopped_by = what
        waiting, self._withdrawable = self._withdrawable, {}
        for written, sent in waiting.items():
            if not written.done():
                written.set_exception(_superseded(sent, what))
        self.drive.end(what)
        for listener in list(self.stop_listeners):
            try:
                listener(what)
            except Exception:
                _log.exception("stop listener %r failed", listener)

    def withdrawable(self, what: str, stops_at: int | None) -> asyncio.Future[bool]:
        """The write future of drive or goal command ``what``, which a user stop fails.

        ``stops_at`` is ``stops`` when the user's call began (None: now): a command of a call
        that a stop has already superseded raises CommandSuperseded at once.
        """
        if stops_at is not None and stops_at != self.stops:
            raise _superseded(what, self._stopped_by)
        written: asyncio.Future[bool] = asyncio.get_running_loop().create_future()
        self._withdrawable[written] = what
        return written

    def moving(self, halt: Callable[[str], None], *, task: str | None = None) -> Callable[[], None]:
        """Register a call awaiting motion (following HTTP ``task``); ``halt(by)`` ends it now.

        Returns the function that unregisters it.
        """
        token = object()
        self._motions[token] = (halt, task)

        def done() -> None:
            self._motions.pop(token, None)

        return done

    def halt_motions(self, by: str) -> list[str | None]:
        """End every call awaiting motion now (stop()); the HTTP task each followed, or None."""
        motions, self._motions = self._motions, {}
        for halt, _task in motions.values():
            halt(by)
        return [task for _halt, task in motions.values()]

    def hold(self, work: Coroutine[Any, Any, _R]) -> asyncio.Task[_R]:
        """Run ``work`` as a task its caller's cancellation does not stop (held until done)."""
        task = asyncio.ensure_future(work)
        self.held.add(task)
        task.add_done_callback(self.held.discard)
        task.add_done_callback(_retrieved)
        return task

    def settled(self, written: asyncio.Future[bool]) -> None:
        """The send of ``written`` is over, written or not."""
        self._withdrawable.pop(written, None)
        if written.done() and not written.cancelled():
            written.exception()  # retrieved: a failure nobody awaited is not logged


def _retrieved(task: asyncio.Future[Any]) -> None:
    if not task.cancelled():
        task.exception()  # a failure whose caller was cancelled is not logged as unretrieved


def goal_superseded(exc: CommandSuperseded, target_id: int) -> GoalCancelled:
    """The GoalCancelled of a goal a user stop superseded before its ``g N`` was written."""
    return GoalCancelled(
        f"goal {target_id} was cancelled before it was sent: {exc}",
        target_id=target_id,
        cancelled_by=exc.superseded_by,
    )


def _superseded(what: str, stop: str) -> CommandSuperseded:
    return CommandSuperseded(
        f"{what}: not sent: {stop} was called while it waited to be written", superseded_by=stop
    )
