"""Events, pure (no I/O): two statuses in, events out; the goal's by the goal machine (goal.py)."""

from __future__ import annotations

from ..events import (
    BusyEnded,
    BusyStarted,
    ChargeStateChanged,
    Event,
    GoalAbortedEvent,
    GoalAccepted,
    GoalCancelledEvent,
    GoalEvent,
    GoalPaused,
    GoalReached,
    GoalRejectedEvent,
    GoalResumed,
    MappingStarted,
    MappingStopped,
    NavigationClosed,
    NavigationOpened,
    PatrolStarted,
    PatrolStopped,
    VisualInitialised,
    VisualLost,
    VisualRecovered,
)
from ..models import GalileoStatus, VisualStatus
from .goal import (
    DEFAULT_ARRIVE_TOLERANCE,
    GoalChange,
    GoalStep,
    SentGoal,
    goal_step,
    running_distance,
)

__all__ = ["derive_events", "derive_step", "step_events"]

_INITIALISED = (VisualStatus.TRACKING, VisualStatus.LOST)


def derive_events(
    prev: GalileoStatus | None,
    cur: GalileoStatus,
    *,
    arrive_tolerance: float = DEFAULT_ARRIVE_TOLERANCE,
    last_distance: float | None = None,
    sent: SentGoal | None = None,
) -> list[Event]:
    """Events for prev → cur (a field unknown on either side: no change); goals by goal_step."""
    if prev is None:
        return []
    tolerance, last = arrive_tolerance, last_distance
    return derive_step(prev, cur, arrive_tolerance=tolerance, last_distance=last, sent=sent)[0]


def derive_step(
    prev: GalileoStatus,
    cur: GalileoStatus,
    *,
    arrive_tolerance: float = DEFAULT_ARRIVE_TOLERANCE,
    last_distance: float | None = None,
    sent: SentGoal | None = None,
    measured: GalileoStatus | None = None,
) -> tuple[list[Event], SentGoal | None]:
    """derive_events, and the SentGoal after cur to keep; ``measured`` gives last_distance."""
    if last_distance is None:
        last_distance = running_distance(measured, prev)
    step = goal_step(
        prev, cur, sent=sent, arrive_tolerance=arrive_tolerance, last_distance=last_distance
    )
    return step_events(prev, cur, step), step.sent


def step_events(prev: GalileoStatus, cur: GalileoStatus, step: GoalStep) -> list[Event]:
    """Events for prev → cur, the goal's told by ``step`` (GoalMachine.step, or goal_step)."""
    out: list[Event] = []
    _two_state(out, prev.nav_status, cur.nav_status, cur, NavigationOpened, NavigationClosed)
    _visual(out, prev.visual_status, cur.visual_status, cur)
    for change, target_id in step.changes:
        out.append(_goal_event(change, target_id, step.distance, cur))
    _two_state(out, prev.busy_status, cur.busy_status, cur, BusyStarted, BusyEnded)
    old, new = prev.charge_status, cur.charge_status
    if old is not None and new is not None and old != new:
        out.append(ChargeStateChanged(status=cur, old=old, new=new))
    _two_state(out, prev.loop_status, cur.loop_status, cur, PatrolStarted, PatrolStopped)
    _two_state(out, prev.map_status, cur.map_status, cur, MappingStarted, MappingStopped)
    return out


def _two_state(
    out: list[Event],
    old: int | None,
    new: int | None,
    cur: GalileoStatus,
    on: type[Event],
    off: type[Event],
) -> None:
    if old is None or new is None or (old == 1) == (new == 1):
        return
    out.append(on(status=cur) if new == 1 else off(status=cur))


def _visual(
    out: list[Event], old: VisualStatus | None, new: VisualStatus | None, cur: GalileoStatus
) -> None:
    if old is None or new is None or old == new:
        return
    was, now = old in _INITIALISED, new in _INITIALISED
    if now and not was:
        out.append(VisualInitialised(status=cur))
    elif new == VisualStatus.LOST or (was and not now and old != VisualStatus.LOST):
        out.append(VisualLost(status=cur))
    elif old == VisualStatus.LOST and new == VisualStatus.TRACKING:
        out.append(VisualRecovered(status=cur))


_SIMPLE_GOAL_EVENTS: dict[GoalChange, type[GoalEvent]] = {
    GoalChange.ACCEPTED: GoalAccepted,
    GoalChange.PAUSED: GoalPaused,
    GoalChange.RESUMED: GoalResumed,
    GoalChange.REJECTED: GoalRejectedEvent,
}


def _goal_event(
    change: GoalChange, target_id: int | None, distance: float | None, cur: GalileoStatus
) -> GoalEvent:
    if change is GoalChange.REACHED or change is GoalChange.ABORTED:
        end = GoalReached if change is GoalChange.REACHED else GoalAbortedEvent
        return end(status=cur, target_id=target_id, distance=distance)
    if change is GoalChange.CANCELLED or change is GoalChange.PREEMPTED:
        preempted = change is GoalChange.PREEMPTED
        return GoalCancelledEvent(status=cur, target_id=target_id, preempted=preempted)
    return _SIMPLE_GOAL_EVENTS[change](status=cur, target_id=target_id)
