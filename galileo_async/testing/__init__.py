"""Test an application without a robot: simulated_robot(), its device side, a virtual clock.

``async with simulated_robot() as (robot, device)`` gives a connected Robot and the device
side of the same simulated robot (the commands it received, scripted faults, time). The
pytest plugin (the module ``galileo_async_pytest``, loaded by pytest through its entry
point) gives the fixtures ``galileo_robot`` and ``galileo_device`` and the ``galileo_sim``
marker. See docs/testing.md.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from .clock import UnsupportedLoop, VirtualClock
    from .device import ReceivedCommand, SimulatedDevice
    from .fleet import simulated_fleet
    from .leaks import LeakCheck
    from .missions import MissionPlay, play_mission
    from .replay import recorded_statuses, replayed_robot
    from .robot import Clock, map_of, simulated_robot

__all__ = [
    "Clock",
    "LeakCheck",
    "MissionPlay",
    "ReceivedCommand",
    "SimulatedDevice",
    "UnsupportedLoop",
    "VirtualClock",
    "map_of",
    "play_mission",
    "recorded_statuses",
    "replayed_robot",
    "simulated_fleet",
    "simulated_robot",
]

# Each name loads its module on first use: importing the package loads none of them.
_LAZY: dict[str, str] = {
    "UnsupportedLoop": "clock",
    "VirtualClock": "clock",
    "ReceivedCommand": "device",
    "SimulatedDevice": "device",
    "simulated_fleet": "fleet",
    "LeakCheck": "leaks",
    "MissionPlay": "missions",
    "play_mission": "missions",
    "recorded_statuses": "replay",
    "replayed_robot": "replay",
    "Clock": "robot",
    "map_of": "robot",
    "simulated_robot": "robot",
}


def __dir__() -> list[str]:
    """The public names (``__all__``) and the module's dunders."""
    dunders = {name for name in globals() if name.startswith("__") and name.endswith("__")}
    dunders.difference_update(("__getattr__", "__dir__"))
    return sorted({*__all__, *dunders})


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{module}", __name__), name)
    globals()[name] = value
    return value
