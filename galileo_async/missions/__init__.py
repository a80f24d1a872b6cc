"""Missions: plans of steps checked before they move a robot (docs/missions.md)."""

from __future__ import annotations

from .capabilities import Unsupported, needs, unsupported
from .check import Problem, check_mission, check_static
from .events import (
    LoopStarted,
    MissionEnded,
    MissionEvent,
    MissionEventStream,
    StepEnded,
    StepStarted,
    mission_events,
)
from .files import MissionFileError, dump_mission, load_mission, mission_schema, parse_mission
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
    "MissionFileError",
    "MissionRejected",
    "MissionReport",
    "OnFailure",
    "Point",
    "PoseGoal",
    "Problem",
    "Release",
    "Step",
    "StepEnded",
    "StepReport",
    "StepStarted",
    "Unsupported",
    "check_mission",
    "check_static",
    "dump_mission",
    "load_mission",
    "mission_events",
    "mission_schema",
    "needs",
    "parse_mission",
    "plan_hash",
    "run_mission",
    "unsupported",
    "walk",
]
