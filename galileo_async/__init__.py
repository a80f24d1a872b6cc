"""galileo_async: an asyncio driver for the Galileo visual navigation system."""

from __future__ import annotations

import importlib
import logging
import types
from typing import TYPE_CHECKING, Any

from . import errors, protocol
from ._wire import (
    AngleGoalStatus,
    ChargeStatus,
    LinkState,
    MapStatus,
    NavStatus,
    StatusLayout,
    TargetStatus,
    VisualStatus,
)
from .errors import *  # noqa: F403

if TYPE_CHECKING:
    from .fleet import Fleet, FleetResult, connect_fleet
    from .models import GalileoStatus, Pose
    from .robot import Connection, GoalResult, Robot, StopReport, connect
    from .ros.discovery import DiscoveredRobot, discover

__version__ = "0.1.0"

# A library never configures logging; this only silences "no handler" warnings.
logging.getLogger(__name__).addHandler(logging.NullHandler())

__all__ = [
    "AngleGoalStatus",
    "ChargeStatus",
    "Connection",
    "DiscoveredRobot",
    "Fleet",
    "FleetResult",
    "GalileoStatus",
    "GoalResult",
    "LinkState",
    "MapStatus",
    "NavStatus",
    "Pose",
    "Robot",
    "StatusLayout",
    "StopReport",
    "TargetStatus",
    "VisualStatus",
    "__version__",
    "connect",
    "connect_fleet",
    "discover",
    "errors",
    "protocol",
    *errors.__all__,
]

# The asyncio layers load on first use, so ``import galileo_async.protocol`` stays I/O-free;
# the pydantic models too, so that ``import galileo_async`` costs no pydantic.
_LAZY: dict[str, str] = {
    "GalileoStatus": "models",
    "Pose": "models",
    "DiscoveredRobot": "ros.discovery",
    "discover": "ros.discovery",
    "Fleet": "fleet",
    "FleetResult": "fleet",
    "connect_fleet": "fleet",
    "Connection": "robot",
    "GoalResult": "robot",
    "Robot": "robot",
    "StopReport": "robot",
    "connect": "robot",
}


def __dir__() -> list[str]:
    """The public names (``__all__``), the module's dunders and its loaded public submodules."""
    dunders = {name for name in globals() if name.startswith("__") and name.endswith("__")}
    submodules = {
        name
        for name, value in globals().items()
        if isinstance(value, types.ModuleType)
        and value.__name__ == f"{__name__}.{name}"
        and not name.startswith("_")
    }
    shown = {*__all__, *dunders, *submodules}
    shown.difference_update(("__getattr__", "__dir__"))
    return sorted(shown)


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{module}", __name__), name)
    globals()[name] = value
    return value
