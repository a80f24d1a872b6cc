"""Missions: plans of steps checked before they move a robot (docs/missions.md)."""

from __future__ import annotations

from .capabilities import Unsupported, needs, unsupported
from .events import (
    LoopStarted,
    MissionEnded,
    MissionEvent,
    MissionEventStream,
    StepEnded,
    StepStarted,
    mission_events,
)
from .journal import Journal, plan_hash
from .model import (
    ACTION_KEYS,
    CallOut,
    ChargeUntil,
    LinkLossPolicy,
    LocalMove,
    Loop,
    MapSwitch,
    Mission,
    OnFailure,
    Point,
    PoseGoal,
    Release,
    Step,
    walk,
)
from .report import MissionRejected, MissionReport, StepReport
from .runner import run_mission

__all__ = [
    "ACTION_KEYS",
    "CallOut",
    "ChargeUntil",
    "Journal",
    "LinkLossPolicy",
    "LocalMove",
    "Loop",
    "LoopStarted",
    "MapSwitch",
    "Mission",
    "MissionEnded",
    "MissionEvent",
    "MissionEventStream",
    "MissionRejected",
    "MissionReport",
    "OnFailure",
    "Point",
    "PoseGoal",
    "Release",
    "Step",
    "StepEnded",
    "StepReport",
    "StepStarted",
    "Unsupported",
    "mission_events",
    "needs",
    "plan_hash",
    "run_mission",
    "unsupported",
    "walk",
]
