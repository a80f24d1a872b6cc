"""Building blocks of Robot operations: deadlines, preconditions, busy back-off, confirmation."""

from __future__ import annotations

import asyncio
import enum
import logging
from collections.abc import Callable
from typing import TYPE_CHECKING, Final, TypeVar

import anyio
import anyio.lowlevel

from ._checks import check_timeout
from .errors import (
    ConnectionLost,
    GalileoConnectionError,
    GalileoError,
    GalileoTimeout,
    LinkStale,
    NotReady,
    OperationFailed,
    OperationTimeout,
    UnconfirmedOperation,
)
from .events import AbandonedGoalCancelled
from .models import GalileoStatus
from .protocol import Cancel, Command, Goto

if TYPE_CHECKING:
    from .link import BaseLink
    from .state import StatusStore

__all__ = [
    "CANCEL_SEND_TIMEOUT",
    "CLEANUP_TIMEOUT",
    "DEFAULT_TIMEOUT",
    "ROBOT_DEFAULT",
    "ROTATE_TIMEOUT",
    "Deadline",
    "DynamicTargets",
    "Operations",
    "RobotDefault",
    "check_timeout",
    "finish_shielded",
    "or_default",
]

_log = logging.getLogger(__name__)

#: Seconds for the status to confirm a simple command (patrol, mapping, pause …).
DEFAULT_TIMEOUT = 10.0
#: Seconds for a rotation to finish.
ROTATE_TIMEOUT = 20.0
#: Longest a shielded cancel (``i 2``) sent on the way out of an operation may take.
CANCEL_SEND_TIMEOUT = 1.0
#: Longest a caller waits for a cleanup (close) it cannot cancel; its steps bound themselves.
CLEANUP_TIMEOUT = 8.0

Predicate = Callable[[GalileoStatus], bool]
_T = TypeVar("_T")


class RobotDefault(enum.Enum):
    """The type of ROBOT_DEFAULT: an argument left out, so the Robot's own setting applies."""

    ROBOT_DEFAULT = "ROBOT_DEFAULT"

    def __repr__(self) -> str:
        return self.value


#: A timeout left out: the Robot's ``goal_timeout`` or ``wait_timeout`` applies (None: no limit).
ROBOT_DEFAULT: Final = RobotDefault.ROBOT_DEFAULT


def or_default(value: _T | RobotDefault, default: _T) -> _T:
    """``default`` when ``value`` is ROBOT_DEFAULT, else ``value``."""
    return default if isinstance(value, RobotDefault) else value


async def finish_shielded(task: asyncio.Task[None], what: str) -> None:
    """Wait for ``task`` (at most CLEANUP_TIMEOUT s) whatever cancels the caller, then re-raise.

    Neither asyncio's ``task.cancel()`` nor an anyio cancel scope interrupts the wait; the
    cancellation that arrived meanwhile is raised once ``task`` is done, so cleanup such as
    close() completes on every exit path and the caller still sees its cancellation.
    """
    loop = asyncio.get_running_loop()
    deadline = loop.time() + CLEANUP_TIMEOUT
    cancelled: asyncio.CancelledError | None = None
    # The anyio shield stops an anyio scope from cancelling the wait again and again; the
    # loop absorbs asyncio cancellations (task.cancel(), asyncio.timeout).
    with anyio.CancelScope(shield=True):
        while not task.done():
            remaining = deadline - loop.time()
            if remaining <= 0:
                _log.warning("%s did not finish within %s s", what, CLEANUP_TIMEOUT)
                break
            try:
                await asyncio.wait((task,), timeout=remaining)
            except asyncio.CancelledError as exc:
                cancelled = exc
    if task.done() and not task.cancelled() and task.exception() is not None:
        if cancelled is None:
            task.result()  # raises the cleanup's own error
        _log.warning("%s failed: %r", what, task.exception())
    if cancelled is not None:
        raise cancelled
    # An anyio scope cancelled meanwhile raises here, as its next checkpoint would.
    await anyio.lowlevel.checkpoint_if_cancelled()


class Deadline:
    """An absolute point in loop time, or none (wait for ever)."""

    __slots__ = ("at", "start", "timeout")

    def __init__(self, timeout: float | None) -> None:
        self.start = asyncio.get_running_loop().time()
        self.timeout = timeout
        self.at = None if timeout is None else self.start + timeout

    def remaining(self) -> float | None:
        """Seconds left (never negative), or None without a deadline."""
        if self.at is None:
            return None
        return max(0.0, self.at - asyncio.get_running_loop().time())

    def elapsed(self) -> float:
        """Seconds since the deadline was set."""
        return asyncio.get_running_loop().time() - self.start


class Operations:
    """Send commands on behalf of a Robot, after checks, and wait for their effect."""

    def __init__(self, link: BaseLink, store: StatusStore) -> None:
        self.link = link
        self.store = store
        # Exit cancels still being written; held here so they finish and close() awaits them.
        self._cancels: set[asyncio.Future[None]] = set()
        #: Goals started through this object (goal_started); an abandoned goal's follow-up
        #: does nothing once a newer goal was started.
        self.goals_started = 0

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

    def check_link(self, what: str) -> None:
        """Raise LinkStale or ConnectionLost, saying nothing was sent, while the link is down."""
        error = self.store.link_error
        if error is None:
            return
        message = f"{what}: nothing was sent: {error}"
        if isinstance(error, LinkStale):
            raise LinkStale(message, silent_for=error.silent_for)
        raise ConnectionLost(message)

    async def transmit(self, command: Command, what: str) -> None:
        """Send ``command`` once, unless the link is lost or stale (the robot unwatched)."""
        self.check_link(what)
        await self.link.send(command)

    def require(self, ok: Predicate, message: str) -> GalileoStatus:
        """Check the link, then return the latest status if ``ok`` holds; else raise NotReady."""
        self.check_link(message.partition(":")[0])
        status = self.store.status
        if status is None:
            raise NotReady(f"{message}: no status has been received from the robot yet", None)
        if not ok(status):
            raise NotReady(message, status)
        return status

    async def ready(self, ok: Predicate, message: str, deadline: Deadline) -> GalileoStatus:
        """As require(), first waiting within ``deadline`` for the robot's first status.

        Before it, the link may be up with only the serial node's placeholder frames
        (PROTOCOL.md §1): after a node restart navigation is open, just not reported yet.
        """
        if self.store.status is None:
            self.check_link(message.partition(":")[0])
            try:
                await self.store.wait_until(lambda _status: True, timeout=deadline.remaining())
            except GalileoTimeout:
                raise NotReady(
                    f"{message}: the navigation system has not reported within "
                    f"{deadline.timeout} s"
                    + (" (only placeholder frames came)" if self.store.awaiting_robot else ""),
                    None,
                ) from None
        return self.require(ok, message)

    async def wait_not_busy(self, deadline: Deadline, what: str) -> None:
        """Wait while busy_status is 1 (the robot would only queue the command), within deadline."""
        status = self.store.status
        if status is None or not status.is_busy:
            return
        try:
            await self.store.wait_until(lambda s: not s.is_busy, timeout=deadline.remaining())
        except GalileoTimeout as exc:
            raise OperationTimeout(
                f"{what}: the robot stayed busy (busy_status 1) for {deadline.elapsed():.1f} s",
                exc.status,
            ) from None

    async def send(self, command: Command, deadline: Deadline, what: str) -> None:
        """Wait out busy_status, then send ``command`` once."""
        await self.wait_not_busy(deadline, what)
        await self.transmit(command, what)

    async def send_confirmed(
        self,
        command: Command,
        done: Predicate,
        *,
        field: str,
        deadline: Deadline,
        what: str,
        failed: Predicate | None = None,
    ) -> GalileoStatus:
        """Send ``command``, then return the first later status where ``done`` holds.

        Raises UnconfirmedOperation when the status layout lacks ``field`` or the deadline
        passes, OperationFailed when ``failed`` holds for a later status.
        """
        await self.wait_not_busy(deadline, what)
        with self.store.watch() as watch:
            await self.transmit(command, what)
            latest = self.store.status
            if latest is not None and getattr(latest, field) is None:
                raise UnconfirmedOperation(
                    f"{what}: sent, but the {latest.layout} status layout has no {field} "
                    "field, so the driver cannot confirm it",
                    latest,
                )
            while True:
                try:
                    status = await watch.next(deadline.remaining())
                except (TimeoutError, asyncio.TimeoutError):
                    raise UnconfirmedOperation(
                        f"{what}: sent, but {field} did not show it within {deadline.timeout} s",
                        self.store.status,
                    ) from None
                if failed is not None and failed(status):
                    raise OperationFailed(f"{what}: the robot reported a failure", status)
                if done(status):
                    return status

    def queue_exit_cancel(self) -> asyncio.Future[bool] | None:
        """Queue Cancel (``i 2``) now, in call order; a goal (``g``) queued after it drops it.

        A dropped exit cancel is not needed: the newer goal replaces the old one on the
        robot (PROTOCOL.md §2.b), and written after it the cancel would stop the new goal.
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
        task = asyncio.ensure_future(self._await_cancel(written))
        self._cancels.add(task)
        task.add_done_callback(self._cancels.discard)
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
        if self._cancels:
            await asyncio.wait(set(self._cancels), timeout=CANCEL_SEND_TIMEOUT)


def _log_unsent_cancel(written: asyncio.Future[bool]) -> None:
    if not written.cancelled() and written.exception() is not None:
        _log.warning("the cancel (i 2) could not be sent: %r", written.exception())


class DynamicTargets:
    """The driver's count of dynamic targets on the robot (no status field shows it)."""

    def __init__(self, link: BaseLink) -> None:
        self._link = link
        self._count: int | None = None  # unknown until reset_targets in this session
        self._reconnects = 0  # link.stats.reconnects when the count was last reset

    def resetting(self) -> None:
        """Forget the count until ``reset_done``: the reset may or may not reach the robot."""
        self._count = None
        self._reconnects = self._link.stats.reconnects

    def reset_done(self) -> None:
        """The reset was written: the robot now has no dynamic targets."""
        self._count = 0

    def forget(self) -> None:
        """An add may or may not have reached the robot: the count is unknown."""
        self._count = None

    def reserve(self, map_targets: int, status: GalileoStatus | None, limit: int) -> int:
        """Return the goal id of the next dynamic target and count it; NotReady if unknown."""
        if self._count is not None and self._reconnects != self._link.stats.reconnects:
            # A reconnect may mean a restarted robot, which keeps no dynamic targets.
            self._count = None
            raise NotReady(
                "add_target: the link reconnected since reset_targets() (the robot may have "
                "restarted and lost its dynamic targets); call reset_targets() again",
                status,
            )
        if self._count is None:
            raise NotReady(
                "add_target: the number of dynamic targets on the robot is unknown; "
                "call reset_targets() first (goto_point does)",
                status,
            )
        target_id = map_targets + self._count
        if target_id > limit:
            raise NotReady(f"add_target: goal ids stop at {limit}; call reset_targets()", status)
        self._count += 1  # reserved now: concurrent calls get distinct ids
        return target_id
