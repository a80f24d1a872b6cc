"""The Robot: its public methods, one send primitive, goal following and connect()."""

from __future__ import annotations

from .connection import FIRST_STATUS_TIMEOUT, Connection, connect
from .goal import GoalResult
from .robot import (
    DEFAULT_ACCEPT_TIMEOUT,
    DEFAULT_ARRIVE_TOLERANCE,
    DEFAULT_GOAL_TIMEOUT,
    DEFAULT_PROGRESS_TIMEOUT,
    DEFAULT_TIMEOUT,
    DEFAULT_WAIT_TIMEOUT,
    NAVIGATION_TIMEOUT,
    ROBOT_DEFAULT,
    ROTATE_TIMEOUT,
    Robot,
    RobotDefault,
)

__all__ = [
    "DEFAULT_ACCEPT_TIMEOUT",
    "DEFAULT_ARRIVE_TOLERANCE",
    "DEFAULT_GOAL_TIMEOUT",
    "DEFAULT_PROGRESS_TIMEOUT",
    "DEFAULT_TIMEOUT",
    "DEFAULT_WAIT_TIMEOUT",
    "FIRST_STATUS_TIMEOUT",
    "NAVIGATION_TIMEOUT",
    "ROBOT_DEFAULT",
    "ROTATE_TIMEOUT",
    "Connection",
    "GoalResult",
    "Robot",
    "RobotDefault",
    "connect",
]
