"""Transitions, pure (no I/O): two statuses in, events out; the goal rule, written once.

goal.py is the goal state machine (goal_step; GoalMachine, its memory between frames);
derive.py turns two statuses into events, the goal's by that machine. events() (the store)
and GoalTracker (goto, goto_point) are its two users, so every goal ends by one verdict with
one name: GoalRejected ~ GoalRejectedEvent, …
"""

from __future__ import annotations

from .derive import derive_events, derive_step, step_events
from .goal import (
    ACTIVE,
    DEFAULT_ARRIVE_TOLERANCE,
    ENDS,
    FAILED,
    KNOWN,
    GoalChange,
    GoalMachine,
    GoalStep,
    SentGoal,
    arrived,
    at_target,
    end_distance,
    failed_newly,
    goal_step,
    informs,
    run_starts,
    running_distance,
    valid_distance,
)

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
    "derive_events",
    "derive_step",
    "end_distance",
    "failed_newly",
    "goal_step",
    "informs",
    "run_starts",
    "running_distance",
    "step_events",
    "valid_distance",
]
