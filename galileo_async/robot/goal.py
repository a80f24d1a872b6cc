"""Goals: GoalRunner tracks each ``g N`` with a GoalTracker and a ProgressCheck, and pauses,
resumes and cancels the goal."""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

from .._checks import check_timeout
from ..errors import (
    AcceptTimeout,
    ConnectionLost,
    GalileoTimeout,
    GoalCancelled,
    GoalStalled,
    LinkStale,
    OperationTimeout,
    UnconfirmedOperation,
)
from ..events import GoalStalledEvent
from ..models import GalileoStatus, TargetStatus
from ..protocol import Cancel, Command, Goto, Pause, Resume
from ..transitions import SentGoal
from .operations import GOAL_READY, LEAVING, Confirm, Operations, Require, Sent
from .progress import ProgressCheck
from .runtime import Deadline
from .tracker import ALREADY_THERE_FRAMES, ALREADY_THERE_TIME, GoalTracker, cancelling, settled

if TYPE_CHECKING:
    from ..state.streams import Watch

__all__ = [
    "ALREADY_THERE_FRAMES",
    "ALREADY_THERE_TIME",
    "GoalResult",
    "GoalRunner",
    "GoalTracker",
]

_log = logging.getLogger(__name__)

#: How a goto may end while the robot may still drive: it is cancelled on the way out.
_LEAVING = (*LEAVING, GoalStalled)


@dataclass(frozen=True, slots=True)
class GoalResult:
    """A goal that ended free within ``arrive_tolerance`` of its target.

    ``already_there``: the robot stood at the target, and the goal never showed as working.
    """

    target_id: int
    distance: float | None
    elapsed: float
    status: GalileoStatus
    already_there: bool = False


class GoalRunner:
    """Runs the goals of one Robot; a newer goal preempts the running one."""

    def __init__(self, ops: Operations) -> None:
        self._ops = ops
        self._running: _Goal | None = None

    @property
    def running(self) -> int | None:
        """The target id of this Robot's goal being tracked (written), or None."""
        goal = self._running
        return goal.target_id if goal is not None and goal.written else None

    def cancelling(self) -> None:
        """Robot.cancel() was called: the running goal's end is a cancel, not a planner abort."""
        if self._running is not None:
            self._running.revise(cancelling)

    async def pause(self, timeout: float | None) -> None:
        """Pause the working goal (a user stop); see Robot.pause."""
        self._ops.user_stopped("pause()")
        await self._control(Pause(), TargetStatus.WORKING, TargetStatus.PAUSED, timeout)

    async def resume(self, timeout: float | None) -> None:
        """Resume the paused goal; see Robot.resume."""
        await self._control(Resume(), TargetStatus.PAUSED, TargetStatus.WORKING, timeout)

    async def cancel(self, timeout: float | None) -> None:
        """Cancel the goal (a user stop), at once even while busy or stale; see Robot.cancel."""
        ops = self._ops
        ops.user_stopped("cancel()")
        check_timeout("timeout", timeout)
        ops.ensure_open()
        self.cancelling()
        await ops.send(Cancel(), what="cancel", even_stale=True)
        stale = ops.store.link_error
        if isinstance(stale, LinkStale):
            raise LinkStale(
                f"cancel: sent, but the status cannot confirm it: {stale}",
                silent_for=stale.silent_for,
            )
        try:
            await ops.store.wait_until(lambda s: not s.goal_active, timeout=timeout)
        except GalileoTimeout as exc:
            if exc.status is None:  # placeholders only: nothing is known of a goal
                raise UnconfirmedOperation(
                    f"cancel: sent, but the navigation system has not reported within "
                    f"{timeout} s (only placeholder frames came), so no status can show it",
                    None,
                ) from None
            raise UnconfirmedOperation(
                f"cancel: sent, but a goal was still active after {timeout} s", exc.status
            ) from None

    async def _control(
        self, command: Command, needed: TargetStatus, result: TargetStatus, timeout: float | None
    ) -> None:
        """Send pause or resume once the goal is ``needed``; return once it shows ``result``."""
        what = type(command).__name__.lower()
        check_timeout("timeout", timeout)
        await self._ops.send(
            command, what=what, deadline=Deadline(timeout),
            require=Require(
                lambda s: s.target_status == needed, f"the goal must be {needed.name.lower()}"
            ),
            then=Confirm(lambda s: s.target_status == result, field="target_status"),
        )  # fmt: skip

    async def run(
        self,
        command: Goto,
        *,
        deadline: Deadline,
        accept_timeout: float,
        arrive_tolerance: float,
        progress_timeout: float | None,
        cancel_on_exit: bool,
        stops_at: int | None = None,
    ) -> GoalResult:
        """Send ``command`` through Operations.send (supersedable) and track its goal; see goto."""
        ops = self._ops
        goal = _Goal(self, command.target_id, accept_timeout, arrive_tolerance, progress_timeout)
        left = _forget  # what the store's goal rule keeps of it once goto returns
        try:
            return await ops.send(
                command, what=f"goto({goal.target_id})", deadline=deadline, require=GOAL_READY,
                then=goal, supersedable=True, stops_at=stops_at, halt=goal.halted,
            )  # fmt: skip
        except _LEAVING as exc:
            # Leaving while the robot may still drive (also a queued goal a user stop withdrew:
            # it preempted the goal before it): stop it, unless a newer goal replaced this one
            # (a cancel would stop it). Before goal.tracker exists nothing was queued.
            # cancel_on_exit False leaves only a goal the robot has shown accepted: one written
            # and not accepted yet must not start later, unseen.
            tracker = goal.tracker
            unaccepted = (
                tracker is not None and goal.written and not tracker.accepted
                and not _runs(ops.store.status, goal.target_id)  # shown, not yet followed
            )  # fmt: skip
            if tracker is not None and (cancel_on_exit or unaccepted) and not goal.preempted:
                if goal.written and (
                    isinstance(exc, (LinkStale, ConnectionLost)) or ops.store.link_error is not None
                ):
                    ops.abandon(goal.target_id)  # unseen, it may drive on: check once back
                # A stale link may still transmit; a lost one cannot.
                if not isinstance(exc, ConnectionLost):
                    _log.info("goal %d left before its end: sending cancel", goal.target_id)
                    if tracker.accepted:  # its end after our cancel is that cancel
                        left = cancelling
                        goal.revise(cancelling)
                    await ops.send_cancel_shielded()
            if isinstance(exc, GoalStalled):
                ops.store.emit(
                    GoalStalledEvent(
                        status=exc.status, target_id=goal.target_id, stalled_for=exc.stalled_for
                    )
                )
            raise
        finally:
            if goal.halted_by is not None and goal.tracker is not None and goal.tracker.accepted:
                left = cancelling  # stop() sent the cancel: its end is that cancel
            ops.store.revise_tracked_goal(goal, left)
            if self._running is goal:
                self._running = None

    def _start(self, goal: _Goal) -> None:
        """``goal`` is about to be written: it replaces the running one."""
        if self._running is not None:
            self._running.preempted = True
        self._running = goal
        self._ops.goal_started()


def _runs(status: GalileoStatus | None, target_id: int) -> bool:
    """``status`` shows goal ``target_id`` running (working or paused)."""
    return (
        status is not None and status.target_num_id == target_id
        and status.target_status in (TargetStatus.WORKING, TargetStatus.PAUSED)
    )  # fmt: skip


def _forget(sent: SentGoal) -> SentGoal | None:
    """A goal goto no longer tracks: the store's rule stops attributing frames to it."""
    return None


class _Goal:
    """One goto of a Robot: the Follower of its ``g N``."""

    __slots__ = (
        "_runner", "accept_timeout", "arrive_tolerance", "halted_by", "preempted",
        "progress_timeout", "target_id", "task", "tracker", "written",
    )  # fmt: skip

    def __init__(
        self,
        runner: GoalRunner,
        target_id: int,
        accept_timeout: float,
        arrive_tolerance: float,
        progress_timeout: float | None,
    ) -> None:
        self._runner = runner
        self.target_id = target_id
        self.accept_timeout = accept_timeout
        self.arrive_tolerance = arrive_tolerance
        self.progress_timeout = progress_timeout
        self.tracker: GoalTracker | None = None
        self.written = False
        #: A newer goal of this Robot was started.
        self.preempted = False
        #: The call of this Robot that halted the goal ("stop()"), if one did.
        self.halted_by: str | None = None
        #: The HTTP API task the goal's write started (a PoseGoal's), once written.
        self.task: str | None = None

    def halted(self, by: str) -> GoalCancelled:
        """The error that ends this goal's goto at once: ``by`` (stop()) cancels the goal."""
        self.halted_by = by
        task = "" if self.task is None else f" (task {self.task})"
        return GoalCancelled(
            f"goal {self.target_id}{task} was cancelled by {by}",
            target_id=self.target_id,
            status=self._runner._ops.store.status,
            cancelled_by=by,
        )

    def sending(self, before: GalileoStatus | None) -> None:
        """The goal starts now; ``before`` is the latest status as ``g N`` is written."""
        self._runner._start(self)
        self.tracker = tracker = GoalTracker(
            self.target_id, before=before, arrive_tolerance=self.arrive_tolerance, origin=self
        )
        assert tracker.sent is not None
        # events() tracks the goal by the same rule, told what this process sends.
        self._runner._ops.store.track_goal(tracker.sent)

    def revise(self, revise: Callable[[SentGoal], SentGoal | None]) -> None:
        """Change what this process is known to have sent for the goal (tracker and store alike)."""
        if self.tracker is not None and self.tracker.sent is not None:
            self.tracker.sent = revise(self.tracker.sent)
        self._runner._ops.store.revise_tracked_goal(self, revise)

    async def follow(self, watch: Watch, sent: Sent) -> GoalResult:
        """Follow the goal from its write to its end: a GoalResult, or GoalError / timeout."""
        self.written = True
        self.task = sent.task
        tracker = self.tracker
        assert tracker is not None
        ops, deadline, target_id = self._runner._ops, sent.deadline, self.target_id
        loop = asyncio.get_running_loop()
        sent_at = loop.time()
        accept_by = sent_at + self.accept_timeout
        progress: ProgressCheck | None = None  # from acceptance on, unless progress_timeout None
        silent_since: float | None = None  # while the link is stale: when its silence began
        while True:
            self._check(ops.store.status)
            now = loop.time()
            stall_at = None if progress is None else progress.deadline()
            if silent_since is not None:
                # Stale: the robot may drive on unseen, and the link may recover (another
                # program took the UDP stream for a moment). Only the overall timeout runs;
                # a lost link ends the goal (ConnectionLost).
                stall_at = None
                wait = deadline.remaining()
            elif tracker.accepted:
                if now >= accept_by and tracker.sent is not None and tracker.sent.restarting:
                    self.revise(settled)
                wait = deadline.remaining()
                if stall_at is not None and (deadline.at is None or stall_at < deadline.at):
                    wait = max(0.0, stall_at - now)
                else:
                    stall_at = None  # the overall deadline comes first
            else:
                stall_at = None
                wait = accept_by - now
                if deadline.at is not None:
                    wait = min(wait, deadline.at - now)
                wait = max(0.0, wait)
            try:
                status = await watch.next(wait)
            except LinkStale as exc:
                # (Unless frames came back before this task saw the error: nothing to discount.)
                if silent_since is None and isinstance(ops.store.link_error, LinkStale):
                    silent_since = max(sent_at, loop.time() - exc.silent_for)
                    _log.info("goal %d goes on while the link is stale: %s", target_id, exc)
                continue
            except GalileoTimeout:
                if progress is not None and stall_at is not None:
                    # A timer may fire a hair early: the stall deadline is what ended the wait.
                    progress.check(ops.store.status, max(loop.time(), stall_at))
                overall = silent_since is not None or (
                    deadline.at is not None and deadline.at <= accept_by
                )
                raise _timeout(
                    tracker, ops.store.status, deadline, self.accept_timeout, overall=overall
                ) from None
            self._check(status)
            was_accepted = tracker.accepted
            now = loop.time()
            if silent_since is not None:
                # Frames again: the silence counts toward neither accept_timeout nor the stall.
                accept_by += now - silent_since
                if progress is not None:
                    progress.discount(now - silent_since)
                silent_since = None
            elapsed = now - sent_at
            if tracker.feed(status) or tracker.stood_there(status, elapsed):
                _log.debug("goal %d arrived (distance %s)", target_id, tracker.distance)
                return GoalResult(
                    target_id, tracker.distance, elapsed, status, tracker.already_there
                )
            if tracker.accepted and not was_accepted:
                _log.debug("goal %d accepted", target_id)
            if progress is not None:
                progress.feed(status, now)
                progress.check(status, now)
            elif tracker.accepted and self.progress_timeout is not None:
                progress = ProgressCheck(target_id, self.progress_timeout, status, now)

    def _check(self, status: GalileoStatus | None) -> None:
        """Raise GoalCancelled(preempted=True) once a newer goal of this Robot was started."""
        if self.preempted:
            raise GoalCancelled(
                f"goal {self.target_id} was preempted by a newer goal",
                target_id=self.target_id,
                preempted=True,
                status=status,
            )


def _timeout(
    tracker: GoalTracker,
    status: GalileoStatus | None,
    deadline: Deadline,
    accept_timeout: float,
    *,
    overall: bool,
) -> GalileoTimeout:
    target_id = tracker.target_id
    if tracker.accepted:
        last = "unknown" if tracker.distance is None else f"{tracker.distance:.3f} m"
        return OperationTimeout(
            f"goal {target_id} did not end within {deadline.timeout} s (last distance {last})",
            status,
        )
    if overall:
        return OperationTimeout(
            f"goal {target_id} was not accepted before the timeout of {deadline.timeout} s",
            status,
        )
    hint = ""
    if status is not None and status.goal_failed:
        # Real firmware leaves target_num_id alone and reports -1 (docs/protocol.md §2.b): with
        # -1 already showing before the command, a rejection looks like a lost command.
        hint = (
            f"; target_status still shows {int(status.target_status or 0)}, so the robot may"
            " have rejected the id without a visible change (real firmware reports"
            " errors as -1 and leaves target_num_id unchanged)"
        )
    return AcceptTimeout(
        f"the robot did not show goal {target_id} as working within {accept_timeout} s{hint}",
        target_id=target_id,
        status=status,
    )
