"""Operations.send, the one way a Robot sends a command, and what it builds on."""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, TypeVar, overload

import anyio

from .._checks import check_timeout
from ..errors import (
    CommandSuperseded,
    ConnectionLost,
    GalileoConnectionError,
    GalileoError,
    GalileoTimeout,
    LinkStale,
    NotReady,
    OperationTimeout,
    WrongEventLoop,
)
from ..events import AbandonedGoalCancelled
from ..models import GalileoStatus, LinkState
from ..protocol import ApiCall, Backward, Cancel, Command, Forward, Goto, TurnLeft, TurnRight
from .follower import Confirm, Follower, Predicate, Sent, task_of
from .runtime import Deadline
from .supersede import Supersession

if TYPE_CHECKING:
    from ..state.store import StatusStore
    from ..transports import Link

__all__ = [
    "CANCEL_SEND_TIMEOUT",
    "DEFAULT_TIMEOUT",
    "GOAL_READY",
    "LEAVING",
    "NAVIGATING",
    "NOT_NAVIGATING",
    "Confirm",
    "Follower",
    "Halt",
    "Operations",
    "Require",
    "Sent",
    "task_of",
]

_log = logging.getLogger(__name__)

#: Seconds for the status to confirm a simple command (patrol, mapping, pause …).
DEFAULT_TIMEOUT = 10.0
#: Longest a shielded cancel (``i 2``) sent on the way out of an operation may take.
CANCEL_SEND_TIMEOUT = 1.0
#: What a goal leaves on while the robot may still drive, so that its exit cancel follows.
LEAVING = (asyncio.CancelledError, GalileoTimeout, LinkStale, ConnectionLost, CommandSuperseded)

#: What a user stop supersedes while it waits (Supersession.user_stopped) among the commands
#: sent unconfirmed: drive commands, and a goal sent as is with Robot.send().
_SUPERSEDABLE = (Forward, Backward, TurnLeft, TurnRight, Goto)

#: Makes the error that ends a call awaiting motion, from the stop's name ("stop()").
Halt = Callable[[str], GalileoError]
_R = TypeVar("_R")


@dataclass(frozen=True, slots=True)
class Require:
    """A precondition: what the latest status must show before a command goes out."""

    holds: Predicate
    #: Said by NotReady after the operation's name: "navigation must be open".
    reason: str


NAVIGATING = Require(lambda s: s.navigating, "navigation must be open")
NOT_NAVIGATING = Require(lambda s: not s.navigating, "navigation must be closed")
GOAL_READY = Require(
    lambda s: s.navigating and s.visual_initialised,
    "navigation must be open and the visual system initialised",
)


class Operations:
    """Send commands on behalf of one Robot, after checks, and follow their effect.

    The one place of a Robot's preconditions: its loop, open, the link up and fresh, no
    drive session in the way of a goal, and the user's stops (its Supersession).
    """

    def __init__(self, link: Link, store: StatusStore) -> None:
        self.link = link
        self.store = store
        #: What a user stop reaches: waiting drive/goal commands, the drive session, motions.
        self.supersession = Supersession()
        #: The event loop that connected the Robot: its link, timers and futures live there.
        self.loop = asyncio.get_running_loop()
        #: Set by Robot.close(): nothing is sent any more.
        self.closed = False
        #: Goals started through this object (goal_started); an abandoned goal's follow-up
        #: does nothing once a newer goal was started.
        self.goals_started = 0

    @overload
    async def send(
        self, command: Command, *, what: str, deadline: Deadline | None = None,
        require: Require | None = None, unless: Predicate | None = None, then: None = None,
        even_stale: bool = False, supersedable: bool = False, stops_at: int | None = None,
    ) -> None: ...  # fmt: skip
    @overload
    async def send(
        self, command: Command, *, what: str, deadline: Deadline,
        require: Require | None = None, unless: None = None, then: Follower[_R],
        supersedable: bool = False, stops_at: int | None = None, halt: Halt | None = None,
    ) -> _R: ...  # fmt: skip
    @overload
    async def send(
        self, command: Command, *, what: str, deadline: Deadline,
        require: Require | None = None, unless: Predicate, then: Follower[_R],
        supersedable: bool = False, stops_at: int | None = None, halt: Halt | None = None,
    ) -> _R | None: ...  # fmt: skip

    async def send(
        self, command: Command, *, what: str, deadline: Deadline | None = None,
        require: Require | None = None, unless: Predicate | None = None,
        then: Follower[_R] | None = None, even_stale: bool = False,
        supersedable: bool = False, stops_at: int | None = None, halt: Halt | None = None,
    ) -> _R | None:  # fmt: skip
        """Send ``command`` once, the one way a Robot does; ``what`` names it in errors.

        In order: the Robot is open and on its loop (WrongEventLoop); the link is up and
        fresh (ConnectionLost, LinkStale: nothing was sent), unless ``even_stale`` (the
        transmit side may work while the status is silent); with ``require`` or ``then``,
        the robot's first real status, waited for within ``deadline``: before it the link
        may carry only the serial node's placeholders (docs/protocol.md §1); ``require`` holds
        (NotReady); ``unless`` holds: done, nothing is sent (returns None); busy_status 0,
        waited for within ``deadline`` (no deadline: sent at once), then ``require`` again;
        ``then`` registered for every later status (before the write, so no status that
        shows the effect can be missed); the write, through the link's one writer; then
        ``then.follow``, whose result is returned.

        A ``supersedable`` command (drive and goal commands) that a user stop finds waiting
        anywhere before its write (user_stopped) is never written: CommandSuperseded, at
        once; ``stops_at``: ``stops`` when the user's call began (default: now). With
        ``halt`` the call awaits motion: stop() (halt_motions) ends its follow at once with
        the error ``halt(by)`` makes.
        """
        self.ensure_open()
        if not even_stale:
            self.check_link(what)
        user_stops = self.supersession
        written = user_stops.withdrawable(what, stops_at) if supersedable else None
        try:
            status = self.store.status
            followed = require is not None or then is not None
            if status is None and deadline is not None and followed:
                status = await self._first_status(what, require, deadline, written)
            if require is not None:
                self._check(require, what)
            if unless is not None and status is not None and unless(status):
                return None
            if deadline is not None and status is not None and status.is_busy:
                await self._not_busy(what, deadline, written)
                if require is not None:
                    self._check(require, what)
            if not even_stale:
                self.check_link(what)  # the link may have dropped while waiting above
            if then is None:
                await self.link.send(command, written=written)
                return None
            assert deadline is not None, "a command that is followed needs a deadline"
            with self.store.watch() as watch:
                if written is not None and written.done():
                    await written  # superseded: raises before the follower starts anything
                then.sending(self.store.status)
                stop = None if halt is None else (lambda by: watch.halt(halt(by)))
                unregister = None if stop is None else user_stops.moving(stop)
                try:
                    task = task_of(await self.link.send(command, written=written))
                    if stop is not None and unregister is not None and task is not None:
                        unregister()  # the same call, now naming its task for stop()'s report
                        unregister = user_stops.moving(stop, task=task)
                    return await then.follow(watch, Sent(what, deadline, self.store.status, task))
                finally:
                    if unregister is not None:
                        unregister()
        finally:
            if written is not None:
                user_stops.settled(written)

    async def send_unconfirmed(
        self, command: Command, what: str, limit: float | None, require: Require | None = None
    ) -> None:
        """Send ``command`` (busy back-off within ``limit`` s, the caller's timeout); unconfirmed.

        A drive or goal command (f, b, c, d, g) is supersedable: a user stop withdraws it.
        """
        check_timeout("timeout", limit)
        await self.send(
            command, what=what, deadline=Deadline(limit), require=require,
            supersedable=isinstance(command, _SUPERSEDABLE),
        )  # fmt: skip

    async def ask(self, call: ApiCall, *, what: str) -> Any:
        """Make ``call`` through the link's one writer; its answer. ``what`` names it in errors.

        Operations.send's checks first: the Robot is open and on its loop (WrongEventLoop,
        GalileoConnectionError), the link is up (ConnectionLost: nothing was sent). A stale
        link is no reason to refuse: the answer comes back over the call, not the status.
        """
        self.ensure_open()
        if not isinstance(self.store.link_error, LinkStale):
            self.check_link(what)
        return await self.link.send(call)

    def ensure_open(self) -> None:
        """Raise WrongEventLoop off the Robot's loop, GalileoConnectionError once it is closed.

        A held task (a stop()'s writes, under way when close() came) still sends until the
        link closes: close() must not cut a stop in half.
        """
        self.ensure_loop()
        if self.closed and asyncio.current_task() not in self.supersession.held:
            raise GalileoConnectionError("this Robot is closed")

    def ensure_loop(self) -> None:
        """Raise WrongEventLoop unless called on the loop that connected the Robot."""
        try:
            loop = asyncio.get_running_loop()
        except RuntimeError:
            loop = None
        if loop is not self.loop:
            # Its transport, timers and futures live on that loop: from another one a call
            # would hang until some unrelated timer fired, or corrupt the link's state.
            raise WrongEventLoop(
                "this Robot is bound to the event loop that connected it and was called "
                + ("from another event loop" if loop is not None else "with no event loop")
                + "; use asyncio.run_coroutine_threadsafe() to call it from another thread"
            )

    def check_link(self, what: str) -> None:
        """Raise LinkStale or ConnectionLost, saying nothing was sent, while the link is down."""
        state = self.link.state
        if state is not LinkState.STALE and state is not LinkState.LOST:
            return
        error = self.link.error
        if error is None:
            return
        message = f"{what}: nothing was sent: {error}"
        if isinstance(error, LinkStale):
            raise LinkStale(message, silent_for=error.silent_for)
        raise ConnectionLost(message)

    def user_stopped(self, what: str) -> None:
        """A user stop ``what`` ("stop()" …): WrongEventLoop off the loop, else Supersession's."""
        self.ensure_loop()
        self.supersession.user_stopped(what)

    def check_not_driving(self, what: str) -> None:
        """NotReady inside an active drive block: a goal and the drive's speeds would fight."""
        if self.supersession.drive.active:
            raise NotReady(
                f"{what}: a drive session is active; leave its block first", self.store.status
            )

    def _check(self, require: Require, what: str) -> None:
        """Raise NotReady unless the latest status shows ``require``."""
        status = self.store.status
        if status is None:
            raise NotReady(
                f"{what}: {require.reason}: no status has been received from the robot yet", None
            )
        if not require.holds(status):
            raise NotReady(f"{what}: {require.reason}", status)

    async def _first_status(
        self,
        what: str,
        require: Require | None,
        deadline: Deadline,
        abort: asyncio.Future[bool] | None,
    ) -> GalileoStatus:
        """The robot's first real status, within ``deadline``; else NotReady."""
        try:
            return await self.store.wait_until(
                lambda _status: True, deadline.remaining(), abort=abort
            )
        except GalileoTimeout:
            needed = "" if require is None else f": {require.reason}"
            raise NotReady(
                f"{what}{needed}: the navigation system has not reported within "
                f"{deadline.timeout} s"
                + (" (only placeholder frames came)" if self.store.awaiting_robot else ""),
                None,
            ) from None

    async def _not_busy(
        self, what: str, deadline: Deadline, abort: asyncio.Future[bool] | None
    ) -> None:
        """Wait while busy_status is 1 (the robot would only queue the command), within deadline."""
        try:
            await self.store.wait_until(lambda s: not s.is_busy, deadline.remaining(), abort=abort)
        except GalileoTimeout as exc:
            raise OperationTimeout(
                f"{what}: the robot stayed busy (busy_status 1) for {deadline.elapsed():.1f} s",
                exc.status,
            ) from None

    def goal_started(self) -> None:
        """A goal of this Robot is about to be sent: it replaces every earlier one."""
        self.goals_started += 1

    def abandon(self, target_id: int) -> None:
        """Goal ``target_id`` failed with the link down: cancel it if it runs once it is back.

        The robot may go on driving while the host cannot see it (the serial node died, the
        navigation computer did not). The first status after this call (the link has
        recovered then: a lost or stale link carries none) decides: goal ``target_id`` still
        working or paused, and no newer goal started here, gets ``i 2`` and an
        AbandonedGoalCancelled event.
        """
        started = self.goals_started

        def check(status: GalileoStatus) -> None:
            if started != self.goals_started or self.link.closed:
                return
            if status.target_num_id != target_id or not status.goal_active:
                return
            written = self.queue_exit_cancel()
            if written is None:
                return
            written.add_done_callback(_log_unsent_cancel)
            _log.warning("goal %d was abandoned but still runs: sending cancel", target_id)
            self.store.emit(AbandonedGoalCancelled(status=status, target_id=target_id))

        self.store.call_on_next_status(check)

    def queue_exit_cancel(self) -> asyncio.Future[bool] | None:
        """Queue Cancel (``i 2``) now, in call order; a goal (``g``) queued after it drops it.

        A dropped exit cancel is not needed: the newer goal replaces the old one on the
        robot (docs/protocol.md §2.b), and written after it the cancel would stop the new goal.
        """
        if self.link.closed:
            return None  # a closed link cannot carry it
        try:
            return self.link.enqueue(Cancel(), superseded_by=(Goto,))
        except GalileoConnectionError as exc:
            _log.warning("the cancel (i 2) could not be queued: %r", exc)
            return None

    async def send_cancel_shielded(self) -> None:
        """Queue Cancel before any await, then wait for its write even while cancelled; bounded."""
        written = self.queue_exit_cancel()
        if written is None:
            return
        # Its own task: asyncio's task.cancel() (even twice) cannot stop the wait, which an
        # anyio shield alone does not prevent; the task bounds itself by CANCEL_SEND_TIMEOUT.
        task = self.supersession.hold(self._await_cancel(written))
        with anyio.CancelScope(shield=True):
            await asyncio.shield(task)

    async def _await_cancel(self, written: asyncio.Future[bool]) -> None:
        try:
            if not await asyncio.wait_for(written, CANCEL_SEND_TIMEOUT):
                _log.info("the cancel (i 2) was dropped: a newer goal replaces the goal")
        except (GalileoError, TimeoutError, asyncio.TimeoutError) as exc:
            _log.warning("the cancel (i 2) could not be sent: %r", exc)

    async def aclose(self) -> None:
        """Wait for exit cancels still being sent (call after link.close(), which fails them)."""
        if self.supersession.held:
            await asyncio.wait(set(self.supersession.held), timeout=CANCEL_SEND_TIMEOUT)


def _log_unsent_cancel(written: asyncio.Future[bool]) -> None:
    if not written.cancelled() and written.exception() is not None:
        _log.warning("the cancel (i 2) could not be sent: %r", written.exception())
