"""The goal state machine, pure (no I/O): goal_step, and GoalMachine, its memory between frames.

goal_step: (prev, cur, what this process sent) → how goals changed. GoalMachine feeds it each
status of one stream against the last that told the goal state. events() (StatusStore,
derive.step_events) and GoalTracker (goto, goto_point) each keep one GoalMachine, so every
goal ends by one verdict with one name: GoalRejected ~ GoalRejectedEvent, …
"""

from __future__ import annotations

from enum import Enum
from typing import NamedTuple

from ..models import GalileoStatus, TargetStatus

__all__ = [
    "ACTIVE",
    "DEFAULT_ARRIVE_TOLERANCE",
    "ENDS",
    "FAILED",
    "KNOWN",
    "GoalChange",
    "GoalMachine",
    "GoalStep",
    "SentGoal",
    "arrived",
    "at_target",
    "end_distance",
    "failed_newly",
    "goal_step",
    "informs",
    "run_starts",
    "running_distance",
    "valid_distance",
]

#: A goal that ends free within this many metres of its target counts as reached.
DEFAULT_ARRIVE_TOLERANCE = 0.3

#: target_status values of a goal that runs (working or paused).
ACTIVE = (TargetStatus.WORKING, TargetStatus.PAUSED)
#: target_status values of an error: 3 in the document, -1 on real firmware (docs/protocol.md §1).
FAILED = (TargetStatus.ERROR, TargetStatus.INVALID)
#: The target_status values the goal rule knows; another (newer firmware) tells nothing.
KNOWN = frozenset(TargetStatus)


class GoalChange(Enum):
    """What happened to a goal between two statuses (ENDS end it); one name per end, as errors."""

    ACCEPTED = "accepted"
    PAUSED = "paused"
    RESUMED = "resumed"
    REACHED = "reached"  # goto returns a GoalResult; events() GoalReached
    ABORTED = "aborted"  # GoalAborted; GoalAbortedEvent
    REJECTED = "rejected"  # GoalRejected; GoalRejectedEvent
    CANCELLED = "cancelled"  # GoalCancelled; GoalCancelledEvent
    PREEMPTED = "preempted"  # GoalCancelled(preempted=True); GoalCancelledEvent(preempted=True)


ENDS = frozenset(GoalChange) - {GoalChange.ACCEPTED, GoalChange.PAUSED, GoalChange.RESUMED}


class SentGoal(NamedTuple):
    """The goal this process sent (SentGoal.written at ``g N``): goal_step's third input."""

    target_id: int
    before_id: int | None  # target_num_id at the write: only a change to ours proves an end
    pending: bool  # written, not yet seen working
    restarting: bool  # sent while it ran: its first end may be the restart's cancel (§2.b)
    cancelled: bool = False  # this process sent cancel (i 2): free far away is that cancel
    origin: object = None  # the sender's own object: tells two sends of one id apart

    @classmethod
    def written(
        cls, target_id: int, before: GalileoStatus | None, origin: object = None
    ) -> SentGoal:
        """``g target_id`` is written now; ``before`` is the latest status at the write."""
        restarting = before is not None and _running(before) and before.target_num_id == target_id
        before_id = None if before is None else before.target_num_id
        return cls(target_id, before_id, not restarting, restarting, origin=origin)


class GoalStep(NamedTuple):
    """goal_step's verdict: (change, goal id) pairs in order, the end's distance, the next sent."""

    changes: tuple[tuple[GoalChange, int | None], ...]
    distance: float | None
    sent: SentGoal | None


def valid_distance(value: float | None) -> float | None:
    """``value`` as a distance in metres, or None when unknown (-1, docs/protocol.md §1)."""
    return value if value is not None and value >= 0.0 else None


def end_distance(status: GalileoStatus, last: float | None) -> float | None:
    """The distance a goal ended at: ``status``'s own when valid, else ``last`` (the last valid)."""
    distance = valid_distance(status.target_distance)
    return last if distance is None else distance


def arrived(distance: float | None, arrive_tolerance: float) -> bool:
    """THE goal rule: a goal that ended free at ``distance`` (end_distance) was reached."""
    # Unknown (no valid distance while it ran, docs/protocol.md §1: -1) cannot prove an arrival.
    return distance is not None and distance <= arrive_tolerance


def at_target(status: GalileoStatus, arrive_tolerance: float) -> bool:
    """``status`` shows its goal free within ``arrive_tolerance`` (its own valid distance)."""
    return status.target_status == TargetStatus.FREE and arrived(
        valid_distance(status.target_distance), arrive_tolerance
    )


def failed_newly(prev: GalileoStatus, cur: GalileoStatus) -> bool:
    """``cur`` shows a goal error that ``prev`` did not already show (for that goal id)."""
    if cur.target_status not in FAILED:
        return False
    return prev.target_status not in FAILED or prev.target_num_id != cur.target_num_id


def _closed(status: GalileoStatus) -> bool:
    return status.nav_status is not None and status.nav_status != 1


def _running(status: GalileoStatus) -> bool:
    # Closing navigation cancels the goal (docs/protocol.md §2.a): one still shown then is gone.
    return status.target_status in ACTIVE and not _closed(status)


def informs(status: GalileoStatus) -> bool:
    """``status`` tells the goal state: a target_status the protocol names, or navigation
    closed (no goal runs then); another value (newer firmware) is no information."""
    return status.target_status in KNOWN or _closed(status)


def goal_step(
    prev: GalileoStatus,
    cur: GalileoStatus,
    *,
    sent: SentGoal | None = None,
    arrive_tolerance: float = DEFAULT_ARRIVE_TOLERANCE,
    last_distance: float | None = None,
) -> GoalStep:
    """THE goal state machine: how goals changed from prev to cur, given ``sent`` (the goal
    this process sent and tracks; None: a watcher). A status that does not inform (informs) on
    either side is no change (GoalMachine compares across it), but a goal this process sent and
    has not seen working is judged by cur alone. A goal shown with navigation closed does not
    run: it ended when navigation closed under it.
    ``last_distance``: the last valid distance of prev's goal before prev (running_distance)."""
    if sent is not None and _closed(cur):  # closed navigation ends every goal, known or not
        gone = prev.target_num_id
        dropped = (
            ((GoalChange.CANCELLED, gone),) if _running(prev) and gone != sent.target_id else ()
        )
        return GoalStep((*dropped, (GoalChange.CANCELLED, sent.target_id)), None, None)
    if not informs(cur):
        return GoalStep((), None, sent)
    if not informs(prev) and (sent is None or not sent.pending):
        return GoalStep((), None, sent)
    if sent is not None and sent.pending:
        if prev.target_num_id == sent.target_id and _running(prev):
            sent = sent._replace(pending=False)  # seen working already (a late listener)
        else:
            return _sent_result(_pending(prev, cur, sent, arrive_tolerance, last_distance), sent)
    if sent is not None and sent.restarting and _restart_cancel(prev, cur, sent, arrive_tolerance):
        return GoalStep((), None, sent._replace(pending=True, restarting=False))
    return _sent_result(_observed(prev, cur, arrive_tolerance, last_distance), sent)


def _restart_cancel(
    prev: GalileoStatus, cur: GalileoStatus, sent: SentGoal, tolerance: float
) -> bool:
    """``cur`` is the restart's own cancel: ours ran, and now it neither runs nor arrived."""
    tid = sent.target_id
    if prev.target_num_id != tid or not _running(prev) or _closed(cur) or failed_newly(prev, cur):
        return False
    return cur.target_num_id != tid or not (_running(cur) or at_target(cur, tolerance))


_Changes = tuple[tuple[GoalChange, int | None], ...]


def _accepted(status: GalileoStatus, target_id: int | None) -> _Changes:
    paused = status.target_status == TargetStatus.PAUSED
    return ((GoalChange.ACCEPTED, target_id),) + (
        ((GoalChange.PAUSED, target_id),) if paused else ()
    )


def _end(distance: float | None, tolerance: float) -> GoalChange:
    return GoalChange.REACHED if arrived(distance, tolerance) else GoalChange.ABORTED


def _pending(
    prev: GalileoStatus, cur: GalileoStatus, sent: SentGoal, tol: float, last: float | None
) -> GoalStep:
    """A written goal not yet seen working: the frames that accept, refuse or end it."""
    tid = sent.target_id
    ours = cur.target_num_id == tid
    # The goal before ours, when ours (or its refusal) shows: a goal this process wrote replaced it.
    before = ((GoalChange.PREEMPTED, prev.target_num_id),) if _running(prev) else ()
    if ours and _running(cur):
        return GoalStep(before + _accepted(cur, tid), None, sent._replace(pending=False))
    if failed_newly(prev, cur):
        # The document reports a bad goal as 3; the firmware as -1, leaving target_num_id
        # unchanged (docs/protocol.md §2.b): an id check cannot be used.
        return GoalStep((*before, (GoalChange.REJECTED, tid)), None, None)
    if ours and sent.before_id != tid and cur.target_status == TargetStatus.FREE:
        # Accepted and finished between two frames: the id changing to ours is the proof.
        distance = valid_distance(cur.target_distance)
        changes = (*before, (GoalChange.ACCEPTED, tid), (_end(distance, tol), tid))
        return GoalStep(changes, distance, None)
    return _observed(prev, cur, tol, last)._replace(sent=sent)  # other goals; ours not yet


def _observed(prev: GalileoStatus, cur: GalileoStatus, tol: float, last: float | None) -> GoalStep:
    """What a watcher that sent nothing sees: the goal ``prev`` shows, the goal ``cur`` shows."""
    old_id, new_id, new = prev.target_num_id, cur.target_num_id, cur.target_status
    # No goal id (-1): a robot that (re)started, not a goal that failed.
    has_id = new_id is not None and new_id >= 0
    if not _running(prev):
        if _running(cur):
            return GoalStep(_accepted(cur, new_id), None, None)
        # Navigation closed: no goal runs, none is refused (an error shown is no new goal's).
        if failed_newly(prev, cur) and has_id and not _closed(cur):
            return GoalStep(((GoalChange.REJECTED, new_id),), None, None)
        return GoalStep((), None, None)
    if _closed(cur):  # navigation closed under the goal: it is gone, and ends here only
        return GoalStep(((GoalChange.CANCELLED, old_id),), None, None)
    if old_id != new_id:
        if _running(cur):
            return GoalStep(((GoalChange.PREEMPTED, old_id), *_accepted(cur, new_id)), None, None)
        rejected = ((GoalChange.REJECTED, new_id),) if new in FAILED and has_id else ()
        return GoalStep(((GoalChange.CANCELLED, old_id), *rejected), None, None)
    if new in ACTIVE:
        if new == prev.target_status:
            return GoalStep((), None, None)
        resumed = GoalChange.PAUSED if new == TargetStatus.PAUSED else GoalChange.RESUMED
        return GoalStep(((resumed, old_id),), None, None)
    if new in FAILED:
        return GoalStep(((GoalChange.REJECTED, old_id),), None, None)
    distance = end_distance(cur, end_distance(prev, last))
    return GoalStep(((_end(distance, tol), old_id),), distance, None)


def _sent_result(step: GoalStep, sent: SentGoal | None) -> GoalStep:
    """``step`` with the end of the ``sent`` goal told as this process's: its cancel, its end."""
    if sent is None:
        return step
    for change, target_id in step.changes:
        if target_id == sent.target_id and change in ENDS:
            if change is GoalChange.ABORTED and sent.cancelled:
                # The document's cancel leaves target_num_id alone (only real firmware sets
                # -1, docs/protocol.md §2.c): free far away after our cancel is that cancel.
                step = step._replace(changes=tuple(
                    (GoalChange.CANCELLED if c is change else c, t) for c, t in step.changes
                ))  # fmt: skip
            return step._replace(sent=None)
    return step if step.sent is not None else step._replace(sent=sent)


def run_starts(prev: GalileoStatus, cur: GalileoStatus) -> bool:
    """``cur`` starts a run of its goal: the distances seen before belong to another run."""
    return _running(cur) and (not _running(prev) or prev.target_num_id != cur.target_num_id)


def running_distance(measured: GalileoStatus | None, prev: GalileoStatus) -> float | None:
    """The valid distance of ``measured`` (the last status with one) if it shows prev's goal run."""
    if measured is None or not _running(measured):
        return None
    if measured.target_num_id != prev.target_num_id:
        return None
    return valid_distance(measured.target_distance)


class GoalMachine:
    """goal_step with its memory, for one stream of statuses (GoalTracker; StatusStore's events()).

    Each status is compared with the last one that informed (informs): one that does not, a
    target_status newer firmware added, is neither an end nor a change. ``measured``, the last
    informing status with a valid distance, gives the end its distance (running_distance).
    """

    __slots__ = ("_latest", "arrive_tolerance", "measured", "prev", "sent")

    def __init__(
        self, *, sent: SentGoal | None = None, arrive_tolerance: float = DEFAULT_ARRIVE_TOLERANCE
    ) -> None:
        self.arrive_tolerance = arrive_tolerance
        #: The goal this process sent, as goal_step tracks it (None: a watcher, or it ended).
        self.sent = sent
        #: The status the next is compared with (None: the next is the first).
        self.prev: GalileoStatus | None = None
        self.measured: GalileoStatus | None = None
        self._latest = False  # prev is the last status given: see() moves it on

    def start(self, status: GalileoStatus | None) -> None:
        """Compare the next status with ``status`` (None: the next is the first); its valid
        distance, if any, becomes the last one measured."""
        self.prev = status
        self._latest = status is not None
        if status is not None and valid_distance(status.target_distance) is not None:
            self.measured = status

    def step(self, status: GalileoStatus) -> GoalStep:
        """How goals changed from the last informing status to ``status``; remembers it."""
        prev = status if self.prev is None else self.prev
        step = goal_step(
            prev,
            status,
            sent=self.sent,
            arrive_tolerance=self.arrive_tolerance,
            last_distance=running_distance(self.measured, prev),
        )
        self.sent = step.sent
        self._latest = informs(status)
        if self._latest:
            if run_starts(prev, status):
                self.measured = None  # its end must not borrow a distance of an earlier run
            self.see(status)
        return step

    def see(self, status: GalileoStatus) -> None:
        """Remember ``status`` without a step: its goal fields are those of the last given."""
        # Hot path (the store, on every frame with an events() consumer): the same fields
        # inform alike, so only the last given status's verdict is looked at.
        if self._latest:
            self.prev = status
            distance = status.target_distance
            if distance is not None and distance >= 0.0:  # -1 is invalid (docs/protocol.md §1)
                self.measured = status
