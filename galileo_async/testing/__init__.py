"""Test an application without a robot: simulated_robot(), its device side, a virtual clock.

``async with simulated_robot() as (robot, device)`` gives a connected Robot and the device
side of the same simulated robot (the commands it received, scripted faults, time). The
pytest plugin (``galileo_async.testing.plugin``, loaded by pytest through its entry point)
gives the fixtures ``galileo_robot`` and ``galileo_device`` and the ``galileo_sim`` marker.
See docs/testing.md.
"""

from __future__ import annotations

from .clock import UnsupportedLoop, VirtualClock
from .device import ReceivedCommand, SimulatedDevice
from .fleet import simulated_fleet
from .leaks import LeakCheck
from .robot import Clock, map_of, simulated_robot

__all__ = [
    "Clock",
    "LeakCheck",
    "ReceivedCommand",
    "SimulatedDevice",
    "UnsupportedLoop",
    "VirtualClock",
    "map_of",
    "simulated_fleet",
    "simulated_robot",
]
