"""Typed transition events and the pure function that derives them from two statuses."""

from __future__ import annotations

import warnings
from dataclasses import dataclass, fields
from typing import ClassVar

from .models import ChargeStatus, GalileoStatus, VisualStatus
from .transitions import DEFAULT_ARRIVE_TOLERANCE, GoalChange, goal_transition

__all__ = [
    "DEFAULT_ARRIVE_TOLERANCE",
    "AbandonedGoalCancelled",
    "BusyEnded",
    "BusyStarted",
    "ChargeStateChanged",
    "ConnectionLostEvent",
    "ConnectionRestored",
    "Event",
    "GoalAbortedEvent",
    "GoalAccepted",
    "GoalCancelledEvent",
    "GoalEvent",
    "GoalFailed",
    "GoalPaused",
    "GoalReached",
    "GoalResumed",
    "LinkRestored",
    "LinkStaleEvent",
    "MappingStarted",
    "MappingStopped",
    "NavigationClosed",
    "NavigationOpened",
    "PatrolStarted",
    "PatrolStopped",
    "VisualInitialised",
    "VisualLost",
    "VisualRecovered",
    "derive_events",
]

_INITIALISED = (VisualStatus.TRACKING, VisualStatus.LOST)


@dataclass(frozen=True, slots=True, kw_only=True)
class Event:
    """Base of every event: ``status`` is the status that showed it (None if none yet)."""

    #: The event's own name, its class name without "Event": what str(), the CLI's JSON
    #: lines and VDA 5050 error references show (e.g. "GoalAborted" for GoalAbortedEvent).
    name: ClassVar[str] = "Event"

    status: GalileoStatus | None

    def __init_subclass__(cls) -> None:
        # No super(): slots=True dataclasses replace the class, which breaks its cell.
        cls.name = cls.__name__.removesuffix("Event") or cls.__name__

    def __str__(self) -> str:
        details = ", ".join(
            f"{f.name}={getattr(self, f.name)!r}" for f in fields(self) if f.name != "status"
        )
        return f"{self.name}({details})"


@dataclass(frozen=True, slots=True, kw_only=True)
class NavigationOpened(Event):
    """The navigation service opened (nav_status 0 → 1)."""


@dataclass(frozen=True, slots=True, kw_only=True)
class NavigationClosed(Event):
    """The navigation service closed (nav_status 1 → 0)."""


@dataclass(frozen=True, slots=True, kw_only=True)
class VisualInitialised(Event):
    """Visual SLAM became initialised (tracking or lost) from off / not initialised."""


@dataclass(frozen=True, slots=True, kw_only=True)
class VisualLost(Event):
    """Visual tracking was lost, or the visual system stopped being initialised."""


@dataclass(frozen=True, slots=True, kw_only=True)
class VisualRecovered(Event):
    """Visual tracking resumed after it was lost (visual_status 2 → 1)."""


@dataclass(frozen=True, slots=True, kw_only=True)
class GoalEvent(Event):
    """Base of the goal events: ``target_id`` is the goal they are about."""

    target_id: int | None


@dataclass(frozen=True, slots=True, kw_only=True)
class GoalAccepted(GoalEvent):
    """A goal started working (a new id, or working after free / error)."""


@dataclass(frozen=True, slots=True, kw_only=True)
class GoalReached(GoalEvent):
    """The goal ended free within the arrive tolerance of its target."""

    distance: float | None


@dataclass(frozen=True, slots=True, kw_only=True)
class GoalAbortedEvent(GoalEvent):
    """The goal ended free far from its target: the planner gave up."""

    distance: float | None


@dataclass(frozen=True, slots=True, kw_only=True)
class GoalFailed(GoalEvent):
    """The goal state became an error (3 in the document, -1 on real firmware)."""


@dataclass(frozen=True, slots=True, kw_only=True)
class GoalCancelledEvent(GoalEvent):
    """The goal was dropped (id changed); ``preempted`` when a new goal replaced it."""

    preempted: bool = False


@dataclass(frozen=True, slots=True, kw_only=True)
class AbandonedGoalCancelled(GoalEvent):
    """A goal left when the link failed still ran once it was back: Cancel (``i 2``) was sent."""


@dataclass(frozen=True, slots=True, kw_only=True)
class GoalPaused(GoalEvent):
    """The working goal was paused."""


@dataclass(frozen=True, slots=True, kw_only=True)
class GoalResumed(GoalEvent):
    """The paused goal is working again."""


@dataclass(frozen=True, slots=True, kw_only=True)
class BusyStarted(Event):
    """The robot became busy: commands wait until it is not."""


@dataclass(frozen=True, slots=True, kw_only=True)
class BusyEnded(Event):
    """The robot is no longer busy."""


@dataclass(frozen=True, slots=True, kw_only=True)
class ChargeStateChanged(Event):
    """charge_status changed from ``old`` to ``new``."""

    old: ChargeStatus
    new: ChargeStatus


@dataclass(frozen=True, slots=True, kw_only=True)
class PatrolStarted(Event):
    """Auto-patrol started (loop_status 0 → 1)."""


@dataclass(frozen=True, slots=True, kw_only=True)
class PatrolStopped(Event):
    """Auto-patrol stopped (loop_status 1 → 0)."""


@dataclass(frozen=True, slots=True, kw_only=True)
class MappingStarted(Event):
    """Map building started (map_status 0 → 1)."""


@dataclass(frozen=True, slots=True, kw_only=True)
class MappingStopped(Event):
    """Map building stopped (map_status 1 → 0)."""


@dataclass(frozen=True, slots=True, kw_only=True)
class LinkStaleEvent(Event):
    """No valid status frame arrived for ``silent_for`` seconds; ``status`` is the last one."""

    silent_for: float


@dataclass(frozen=True, slots=True, kw_only=True)
class LinkRestored(Event):
    """Valid status frames arrive again after the link was stale."""


@dataclass(frozen=True, slots=True, kw_only=True)
class ConnectionLostEvent(Event):
    """The transport dropped; ``reason`` says why."""

    reason: str


@dataclass(frozen=True, slots=True, kw_only=True)
class ConnectionRestored(Event):
    """The transport is connected again after a drop."""


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


#: The events' former names, the same as errors' names (GoalAborted, …): importable from
#: this module for one release, with a DeprecationWarning.
_RENAMED = {
    "GoalAborted": GoalAbortedEvent,
    "GoalCancelled": GoalCancelledEvent,
    "LinkStale": LinkStaleEvent,
    "ConnectionLost": ConnectionLostEvent,
}


def __getattr__(name: str) -> type[Event]:
    """The deprecated event names, each with a DeprecationWarning naming its new name."""
    event = _RENAMED.get(name)
    if event is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    warnings.warn(
        f"galileo_async.events.{name} is deprecated, use {event.__name__}: "
        f"galileo_async.{name} is the error of the same name",
        DeprecationWarning,
        stacklevel=2,
    )
    return event
