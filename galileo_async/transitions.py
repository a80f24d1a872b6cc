"""Transitions, pure (no I/O): two statuses in, events out; the goal rule, written once.

derive_events (the events() stream) and the goal follower of goto/rotate_to both decide a
goal's end with goal_transition, so a goal that goto() reports reached is the goal that
events() reports reached.
"""

from __future__ import annotations

from enum import Enum
from typing import NamedTuple

from .events import (
    BusyEnded,
    BusyStarted,
    ChargeStateChanged,
    Event,
    GoalAbortedEvent,
    GoalAccepted,
    GoalCancelledEvent,
    GoalEvent,
    GoalFailed,
    GoalPaused,
    GoalReached,
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
from .models import GalileoStatus, TargetStatus, VisualStatus

__all__ = [
    "ACTIVE",
    "DEFAULT_ARRIVE_TOLERANCE",
    "FAILED",
    "GoalChange",
    "GoalTransition",
    "arrived",
    "derive_events",
    "end_distance",
    "goal_transition",
    "running_distance",
    "valid_distance",
]

#: A goal that ends free within this many metres of its target counts as reached.
DEFAULT_ARRIVE_TOLERANCE = 0.3

#: target_status values of a goal that runs (working or paused).
ACTIVE = (TargetStatus.WORKING, TargetStatus.PAUSED)
#: target_status values of an error: 3 in the document, -1 on real firmware (PROTOCOL.md §1).
FAILED = (TargetStatus.ERROR, TargetStatus.INVALID)


class GoalChange(Enum):
    """What happened to the goal between two statuses."""

    ACCEPTED = "accepted"
    PAUSED = "paused"
    RESUMED = "resumed"
    REACHED = "reached"
    ABORTED = "aborted"
    FAILED = "failed"
    CANCELLED = "cancelled"
    PREEMPTED = "preempted"  # cancelled because a new goal replaced it (ACCEPTED follows)


class GoalTransition(NamedTuple):
    """The goal's changes between two statuses, in order; ``distance`` for REACHED/ABORTED."""

    changes: tuple[GoalChange, ...]
    distance: float | None = None


_NONE = GoalTransition(())


def valid_distance(value: float | None) -> float | None:
    """``value`` as a distance in metres, or None when unknown (-1 is invalid, PROTOCOL.md §1)."""
    return value if value is not None and value >= 0.0 else None


def end_distance(status: GalileoStatus, last: float | None) -> float | None:
    """The distance a goal ended at: ``status``'s own when valid, else ``last`` (the last valid)."""
    distance = valid_distance(status.target_distance)
    return last if distance is None else distance


def arrived(distance: float | None, arrive_tolerance: float) -> bool:
    """THE goal rule: a goal that ended free at ``distance`` (end_distance) was reached."""
    # Unknown (no valid distance while it ran, PROTOCOL.md §1: -1) cannot prove an arrival.
    return distance is not None and distance <= arrive_tolerance


def goal_transition(
    prev: GalileoStatus,
    cur: GalileoStatus,
    *,
    arrive_tolerance: float = DEFAULT_ARRIVE_TOLERANCE,
    last_distance: float | None = None,
) -> GoalTransition:
    """How the goal changed from ``prev`` to ``cur``; unknown target_status on either side: none.

    ``last_distance``: the last valid distance of the goal ``prev`` shows, seen before
    ``prev`` (running_distance); prev's own valid distance is newer and wins over it.
    """
    old, new = prev.target_status, cur.target_status
    if old is None or new is None:
        return _NONE
    same_id = prev.target_num_id == cur.target_num_id
    if old in ACTIVE:
        if new in ACTIVE and same_id:
            if old == new:
                return _NONE
            paused = new == TargetStatus.PAUSED
            return GoalTransition((GoalChange.PAUSED if paused else GoalChange.RESUMED,))
        if new in FAILED:
            return GoalTransition((GoalChange.FAILED,))
        if not same_id:
            if new in ACTIVE:
                return GoalTransition((GoalChange.PREEMPTED, GoalChange.ACCEPTED))
            return GoalTransition((GoalChange.CANCELLED,))
        distance = end_distance(cur, end_distance(prev, last_distance))
        end = GoalChange.REACHED if arrived(distance, arrive_tolerance) else GoalChange.ABORTED
        return GoalTransition((end,), distance)
    if new in ACTIVE:
        if new == TargetStatus.PAUSED:
            return GoalTransition((GoalChange.ACCEPTED, GoalChange.PAUSED))
        return GoalTransition((GoalChange.ACCEPTED,))
    if new in FAILED and (old not in FAILED or not same_id):
        return GoalTransition((GoalChange.FAILED,))
    return _NONE


def running_distance(measured: GalileoStatus | None, prev: GalileoStatus) -> float | None:
    """The valid distance ``measured`` shows if it shows ``prev``'s goal running, else None.

    ``measured``: the last status with a valid distance before ``prev``'s successor; a
    feeder that keeps it (one comparison a frame) gives goal_transition its last_distance.
    """
    if measured is None or measured.target_status not in ACTIVE:
        return None
    if measured.target_num_id != prev.target_num_id:
        return None
    return valid_distance(measured.target_distance)


_INITIALISED = (VisualStatus.TRACKING, VisualStatus.LOST)


def derive_events(
    prev: GalileoStatus | None,
    cur: GalileoStatus,
    *,
    arrive_tolerance: float = DEFAULT_ARRIVE_TOLERANCE,
    last_distance: float | None = None,
) -> list[Event]:
    """Events for the transition prev → cur; a field unknown (None) on either side is no change.

    The goal's events follow transitions.goal_transition (the goal rule); ``last_distance``
    is the running goal's last valid distance seen before ``prev`` (running_distance), if known.
    """
    if prev is None:
        return []
    out: list[Event] = []
    _two_state(out, prev.nav_status, cur.nav_status, cur, NavigationOpened, NavigationClosed)
    _visual(out, prev.visual_status, cur.visual_status, cur)
    _goal(out, prev, cur, arrive_tolerance, last_distance)
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
    GoalChange.FAILED: GoalFailed,
}


def _goal(
    out: list[Event],
    prev: GalileoStatus,
    cur: GalileoStatus,
    tolerance: float,
    last_distance: float | None,
) -> None:
    transition = goal_transition(prev, cur, arrive_tolerance=tolerance, last_distance=last_distance)
    for change in transition.changes:
        if change is GoalChange.REACHED:
            out.append(
                GoalReached(status=cur, target_id=cur.target_num_id, distance=transition.distance)
            )
        elif change is GoalChange.ABORTED:
            out.append(
                GoalAbortedEvent(
                    status=cur, target_id=cur.target_num_id, distance=transition.distance
                )
            )
        elif change is GoalChange.CANCELLED or change is GoalChange.PREEMPTED:
            preempted = change is GoalChange.PREEMPTED
            out.append(
                GoalCancelledEvent(status=cur, target_id=prev.target_num_id, preempted=preempted)
            )
        else:
            out.append(_SIMPLE_GOAL_EVENTS[change](status=cur, target_id=cur.target_num_id))
