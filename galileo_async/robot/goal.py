"""Goals: GoalTracker (statuses after ``g N`` in, a verdict out; no I/O) and GoalRunner."""

from __future__ import annotations

import asyncio
import logging
from dataclasses import dataclass
from typing import TYPE_CHECKING, NoReturn

from ..errors import (
    AcceptTimeout,
    ConnectionLost,
    GalileoTimeout,
    GoalAborted,
    GoalCancelled,
    GoalRejected,
    LinkStale,
    OperationTimeout,
)
from ..models import GalileoStatus, TargetStatus
from ..protocol import Goto
from ..transitions import ACTIVE, arrived, end_distance, valid_distance
from .operations import GOAL_READY, LEAVING, Operations, Sent
from .runtime import Deadline

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

#: Frames in a row after ``g N`` that must show goal N free within arrive_tolerance, none
#: working, before the goal counts as done "already there" (GoalTracker.stood_there).
ALREADY_THERE_FRAMES = 10
#: Seconds after the write before "already there" may be decided (10 frames at 30 Hz):
#: frames that arrive in a burst may all predate the robot reading the command.
ALREADY_THERE_TIME = ALREADY_THERE_FRAMES / 30


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


def _failed_transition(previous: GalileoStatus | None, status: GalileoStatus) -> bool:
    """True when ``status`` shows a goal error that ``previous`` did not already show."""
    if previous is None or not status.goal_failed:
        return False
    if not previous.goal_failed:
        return True
    return (previous.target_num_id, previous.target_status) != (
        status.target_num_id,
        status.target_status,
    )


class GoalTracker:
    """Decide acceptance and the end of goal ``target_id`` from the statuses after the send.

    ``before`` is the latest status when the command was sent: the first frames after
    ``g N`` may still show it (a cached status re-sent with a new counter, PROTOCOL.md §1),
    so only transitions away from it count, never levels that it already showed.
    """

    def __init__(
        self, target_id: int, *, before: GalileoStatus | None, arrive_tolerance: float
    ) -> None:
        self.target_id = target_id
        self.arrive_tolerance = arrive_tolerance
        self.accepted = False
        self.distance: float | None = None
        #: The goal ended because the robot already stood at the target (no working frame).
        self.already_there = False
        self._there_frames = 0  # frames in a row at the target since the send, none working
        self._previous = before
        self._before_id = before.target_num_id if before is not None else None
        # Re-sending the goal that is already running: the firmware cancels and restarts it
        # (PROTOCOL.md §2.b), which may show one cancelled frame before it works again.
        self._restarting = (
            before is not None and before.target_num_id == target_id and before.goal_active
        )

    def feed(self, status: GalileoStatus) -> bool:
        """Consume one status; True when the goal arrived, GoalError when it ended otherwise."""
        try:
            if status.nav_status is not None and not status.navigating:
                raise GoalCancelled(
                    f"goal {self.target_id} ended: navigation was stopped",
                    target_id=self.target_id,
                    status=status,
                )
            if self.accepted:
                return self._track(status)
            return self._accept(status)
        finally:
            self._previous = status

    def _accept(self, status: GalileoStatus) -> bool:
        ours = status.target_num_id == self.target_id
        if ours and status.target_status == TargetStatus.WORKING:
            self.accepted = True
            self._note_distance(status)
            return False
        if _failed_transition(self._previous, status):
            # The document reports a bad goal as 3; the firmware as -1, leaving
            # target_num_id unchanged (PROTOCOL.md §2.b): an id check cannot be used.
            raise GoalRejected(
                f"the robot rejected goal {self.target_id} "
                f"(target_status {_name(status.target_status)}): no such target, "
                "or it cannot be reached",
                target_id=self.target_id,
                status=status,
            )
        if ours and self._before_id != self.target_id and status.target_status == TargetStatus.FREE:
            # Accepted and finished between two frames: the id changing to ours is the proof.
            self.accepted = True
            return self._track(status)
        if ours and self._near(status):
            self._there_frames += 1
        else:
            self._there_frames = 0
        return False

    def stood_there(self, status: GalileoStatus, since_send: float) -> bool:
        """Whether the goal is done because the robot stood at its target all along.

        Standing at target N already, the firmware may finish ``g N`` within one frame, so
        no frame ever shows it working and the id does not change: only the robot staying
        free at the target (ALREADY_THERE_FRAMES frames in a row up to ``status``, none
        working, and ALREADY_THERE_TIME seconds ``since_send``) tells it is done rather than
        not started.
        """
        if self.accepted or self._there_frames < ALREADY_THERE_FRAMES:
            return False
        if since_send < ALREADY_THERE_TIME:
            return False
        self.accepted = self.already_there = True
        self._note_distance(status)
        return True

    def _track(self, status: GalileoStatus) -> bool:
        state = status.target_status
        ours = status.target_num_id == self.target_id
        if self._restarting and not (ours and (status.goal_active or self._near(status))):
            # The first end seen is the restart's own cancel, not the end of the new goal;
            # free at the target is an arrival either way (the restart may show no cancel).
            self._restarting = False
            self.accepted = False
            return self._accept(status)
        if not ours:
            return self._id_changed(status)
        if state in ACTIVE:
            self._note_distance(status)
            return False
        if state == TargetStatus.FREE:
            self._note_distance(status)
            if arrived(self.distance, self.arrive_tolerance):
                return True
            where = (
                "at an unknown distance" if self.distance is None else (f"{self.distance:.2f} m")
            )
            raise GoalAborted(
                f"goal {self.target_id} stopped short, {where} from the target "
                f"(arrive_tolerance {self.arrive_tolerance} m): the planner gave up",
                target_id=self.target_id,
                distance=self.distance,
                status=status,
            )
        if status.goal_failed:
            raise GoalRejected(
                f"the robot reported an error for goal {self.target_id} while moving "
                f"(target_status {_name(state)})",
                target_id=self.target_id,
                status=status,
            )
        return False  # an unknown target_status value from newer firmware: not an end

    def _id_changed(self, status: GalileoStatus) -> NoReturn:
        preempted = status.goal_active
        what = f"preempted by goal {status.target_num_id}" if preempted else "cancelled"
        raise GoalCancelled(
            f"goal {self.target_id} was {what}",
            target_id=self.target_id,
            preempted=preempted,
            status=status,
        )

    def settle(self) -> None:
        """Stop treating the first end as a restart's cancel (the restart window is over)."""
        self._restarting = False

    def _near(self, status: GalileoStatus) -> bool:
        return status.target_status == TargetStatus.FREE and arrived(
            valid_distance(status.target_distance), self.arrive_tolerance
        )

    def _note_distance(self, status: GalileoStatus) -> None:
        self.distance = end_distance(status, self.distance)


def _name(value: TargetStatus | None) -> str:
    return "unknown" if value is None else f"{int(value)} ({value.name})"


class GoalRunner:
    """Runs the goals of one Robot; a newer goal preempts the running one."""

    def __init__(self, ops: Operations) -> None:
        self._ops = ops
        self._running: _Goal | None = None

    def cancelling(self) -> None:
        """Robot.cancel() was called: the running goal's end is a cancel, not a planner abort."""
        if self._running is not None:
            self._running.cancelled = True

    async def run(
        self,
        command: Goto,
        *,
        deadline: Deadline,
        accept_timeout: float,
        arrive_tolerance: float,
        cancel_on_exit: bool,
        stops_at: int | None = None,
    ) -> GoalResult:
        """Send ``command`` through Operations.send (supersedable) and follow its goal; see goto."""
        ops = self._ops
        goal = _Goal(self, command.target_id, accept_timeout, arrive_tolerance)
        try:
            return await ops.send(
                command, what=f"goto({goal.target_id})", deadline=deadline, require=GOAL_READY,
                then=goal, supersedable=True, stops_at=stops_at,
            )  # fmt: skip
        except LEAVING as exc:
            # Leaving while the robot may still drive (also a queued goal a user stop withdrew:
            # it preempted the goal before it): stop it, unless a newer goal replaced this one
            # (a cancel would stop it). Before goal.tracker exists nothing was queued.
            if goal.tracker is not None and cancel_on_exit and not goal.preempted:
                if goal.written and isinstance(exc, (LinkStale, ConnectionLost)):
                    ops.abandon(goal.target_id)  # unseen, it may drive on: check once back
                # A stale link may still transmit; a lost one cannot.
                if not isinstance(exc, ConnectionLost):
                    _log.info("goal %d left before its end: sending cancel", goal.target_id)
                    await ops.send_cancel_shielded()
            raise
        finally:
            if self._running is goal:
                self._running = None

    def _start(self, goal: _Goal) -> None:
        """``goal`` is about to be written: it replaces the running one."""
        if self._running is not None:
            self._running.preempted = True
        self._running = goal
        self._ops.goal_started()


class _Goal:
    """One goto of a Robot: the Follower of its ``g N``."""

    __slots__ = (
        "_runner", "accept_timeout", "arrive_tolerance", "cancelled", "preempted", "target_id",
        "tracker", "written",
    )  # fmt: skip

    def __init__(
        self, runner: GoalRunner, target_id: int, accept_timeout: float, arrive_tolerance: float
    ) -> None:
        self._runner = runner
        self.target_id = target_id
        self.accept_timeout = accept_timeout
        self.arrive_tolerance = arrive_tolerance
        self.tracker: GoalTracker | None = None
        self.written = False
        #: A newer goal of this Robot was started.
        self.preempted = False
        #: Robot.cancel() was called while this goal ran.
        self.cancelled = False

    def sending(self, before: GalileoStatus | None) -> None:
        """The goal starts now; ``before`` is the latest status as ``g N`` is written."""
        self._runner._start(self)
        self.tracker = GoalTracker(
            self.target_id, before=before, arrive_tolerance=self.arrive_tolerance
        )

    async def follow(self, watch: Watch, sent: Sent) -> GoalResult:
        """Follow the goal from its write to its end: a GoalResult, or GoalError / timeout."""
        self.written = True
        tracker = self.tracker
        assert tracker is not None
        ops, deadline, target_id = self._runner._ops, sent.deadline, self.target_id
        loop = asyncio.get_running_loop()
        sent_at = loop.time()
        accept_by = sent_at + self.accept_timeout
        while True:
            self._check(ops.store.status)
            now = loop.time()
            if tracker.accepted:
                if now >= accept_by:
                    tracker.settle()
                wait = deadline.remaining()
            else:
                wait = accept_by - now
                if deadline.at is not None:
                    wait = min(wait, deadline.at - now)
                wait = max(0.0, wait)
            try:
                status = await watch.next(wait)
            except GalileoTimeout:
                overall = deadline.at is not None and deadline.at <= accept_by
                raise _timeout(
                    tracker, ops.store.status, deadline, self.accept_timeout, overall=overall
                ) from None
            self._check(status)
            was_accepted = tracker.accepted
            elapsed = loop.time() - sent_at
            if self._feed(tracker, status) or tracker.stood_there(status, elapsed):
                _log.debug("goal %d arrived (distance %s)", target_id, tracker.distance)
                return GoalResult(
                    target_id, tracker.distance, elapsed, status, tracker.already_there
                )
            if tracker.accepted and not was_accepted:
                _log.debug("goal %d accepted", target_id)

    def _check(self, status: GalileoStatus | None) -> None:
        """Raise GoalCancelled(preempted=True) once a newer goal of this Robot was started."""
        if self.preempted:
            raise GoalCancelled(
                f"goal {self.target_id} was preempted by a newer goal",
                target_id=self.target_id,
                preempted=True,
                status=status,
            )

    def _feed(self, tracker: GoalTracker, status: GalileoStatus) -> bool:
        """tracker.feed, where an end after Robot.cancel() is a cancel, not a planner abort."""
        try:
            return tracker.feed(status)
        except GoalAborted:
            if not self.cancelled:
                raise
            # The document's cancel leaves target_num_id alone (only real firmware sets -1,
            # PROTOCOL.md §2.c): free far from the target is then our own cancel.
            raise GoalCancelled(
                f"goal {self.target_id} was cancelled", target_id=self.target_id, status=status
            ) from None


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
        return OperationTimeout(
            f"goal {target_id} did not end within {deadline.timeout} s "
            f"(last distance {tracker.distance} m)",
            status,
        )
    if overall:
        return OperationTimeout(
            f"goal {target_id} was not accepted before the timeout of {deadline.timeout} s",
            status,
        )
    hint = ""
    if status is not None and status.goal_failed:
        # Real firmware leaves target_num_id alone and reports -1 (PROTOCOL.md §2.b): with
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
