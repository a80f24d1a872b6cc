"""The Robot: its public methods, one send primitive, goal following and connect()."""

from __future__ import annotations

from ..models import LinkState
from ..transports import LinkStateStream
from .connection import FIRST_STATUS_TIMEOUT, Connection, connect
from .drive import (
    DEFAULT_DRIVE_RATE,
    DEFAULT_MAX_ANGULAR_SPEED,
    DEFAULT_MAX_LINEAR_SPEED,
    MAX_DRIVE_RATE,
    MIN_DRIVE_RATE,
    DriveSession,
    SpeedLimits,
)
from .goal import GoalResult
from .http_part import HttpPart, MapImage, MapPath, NavPoint, RobotInfo
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
from .stopping import DEFAULT_STOP_TIMEOUT, StopReport
from .task_chain import (
    TASK_ENDINGS,
    Action,
    CallbackAction,
    ChargeAction,
    LocalMoveAction,
    NavAction,
    SleepAction,
    Task,
    TaskAction,
    WaitReqAction,
)

__all__ = [
    "DEFAULT_ACCEPT_TIMEOUT",
    "DEFAULT_ARRIVE_TOLERANCE",
    "DEFAULT_DRIVE_RATE",
    "DEFAULT_GOAL_TIMEOUT",
    "DEFAULT_MAX_ANGULAR_SPEED",
    "DEFAULT_MAX_LINEAR_SPEED",
    "DEFAULT_PROGRESS_TIMEOUT",
    "DEFAULT_STOP_TIMEOUT",
    "DEFAULT_TIMEOUT",
    "DEFAULT_WAIT_TIMEOUT",
    "FIRST_STATUS_TIMEOUT",
    "MAX_DRIVE_RATE",
    "MIN_DRIVE_RATE",
    "NAVIGATION_TIMEOUT",
    "ROBOT_DEFAULT",
    "ROTATE_TIMEOUT",
    "TASK_ENDINGS",
    "Action",
    "CallbackAction",
    "ChargeAction",
    "Connection",
    "DriveSession",
    "GoalResult",
    "HttpPart",
    "LinkState",
    "LinkStateStream",
    "LocalMoveAction",
    "MapImage",
    "MapPath",
    "NavAction",
    "NavPoint",
    "Robot",
    "RobotDefault",
    "RobotInfo",
    "SleepAction",
    "SpeedLimits",
    "StopReport",
    "Task",
    "TaskAction",
    "WaitReqAction",
    "connect",
]
