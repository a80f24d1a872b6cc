"""A virtual Galileo on the device side of the protocol; uses ``protocol`` and ``models`` only."""

from __future__ import annotations

from .config import DEFAULT_TARGETS, FRAME_RATE, Faults, SimConfig, parse_sim_url
from .device import DeviceStats, FrameEncoder, Ticker
from .robot_model import SETTABLE_FIELDS, RobotModel
from .simulator import Connector, SimState, Simulator

__all__ = [
    "DEFAULT_TARGETS",
    "FRAME_RATE",
    "SETTABLE_FIELDS",
    "Connector",
    "DeviceStats",
    "Faults",
    "FrameEncoder",
    "RobotModel",
    "SimConfig",
    "SimState",
    "Simulator",
    "Ticker",
    "parse_sim_url",
]
