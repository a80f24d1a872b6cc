"""Typed transition events: what changed, as values (transitions.derive_events makes them)."""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import ClassVar

from .models import ChargeStatus, GalileoStatus

__all__ = [
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
    "GoalPaused",
    "GoalReached",
    "GoalRejectedEvent",
    "GoalResumed",
    "GoalStalledEvent",
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
]


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
class GoalRejectedEvent(GoalEvent):
    """The robot reported an error for the goal (3 in the document, -1 on real firmware)."""


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
class GoalStalledEvent(GoalEvent):
    """A goto made no progress for ``stalled_for`` s (progress_timeout): it was cancelled."""

    stalled_for: float


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
