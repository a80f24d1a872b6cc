"""Missions: plans of steps checked before they move a robot (docs/missions.md)."""

from __future__ import annotations

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
    "OnFailure",
    "Point",
    "PoseGoal",
    "Release",
    "Step",
    "walk",
]
