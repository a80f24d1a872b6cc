"""Missions: plans of steps checked before they move a robot (docs/missions.md)."""

from __future__ import annotations

from .check import Problem, check_mission, check_static
from .files import MissionFileError, dump_mission, load_mission, mission_schema, parse_mission
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

__all__ = [
    "ACTION_KEYS",
    "CallOut",
    "ChargeUntil",
    "LinkLossPolicy",
    "LocalMove",
    "Loop",
    "MapSwitch",
    "Mission",
    "MissionFileError",
    "OnFailure",
    "Point",
    "PoseGoal",
    "Problem",
    "Release",
    "Step",
    "check_mission",
    "check_static",
    "dump_mission",
    "load_mission",
    "mission_schema",
    "parse_mission",
    "walk",
]
