"""galileo_async: an asyncio driver for the Galileo visual navigation system."""

from __future__ import annotations

from . import errors, protocol
from .errors import *  # noqa: F403
from .models import (
    AngleGoalStatus,
    ChargeStatus,
    GalileoStatus,
    MapStatus,
    NavStatus,
    Pose,
    StatusLayout,
    TargetStatus,
    VisualStatus,
)

__version__ = "0.1.0"

__all__ = [
    "AngleGoalStatus",
    "ChargeStatus",
    "GalileoStatus",
    "MapStatus",
    "NavStatus",
    "Pose",
    "StatusLayout",
    "TargetStatus",
    "VisualStatus",
    "__version__",
    "errors",
    "protocol",
    *errors.__all__,
]
