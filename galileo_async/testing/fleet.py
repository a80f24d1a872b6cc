"""simulated_fleet(): a Fleet of simulated robots and the device side of each."""

from __future__ import annotations

import contextlib
from collections.abc import AsyncIterator, Mapping, Sequence
from typing import Any, Literal

from .._checks import check_int
from ..errors import InvalidArgument
from ..fleet import Fleet, connect_fleet
from ..sim import Simulator
from .clock import VirtualClock
from .device import SimulatedDevice
from .robot import Clock, build_simulator

__all__ = ["simulated_fleet"]

#: Most robots one simulated fleet takes (each is a simulator with its own frame timer).
MAX_ROBOTS = 1000


def _names(robots: int | Sequence[str]) -> list[str]:
    if isinstance(robots, int) and not isinstance(robots, bool):
        count = check_int("robots", robots, 1, MAX_ROBOTS)
        return [f"robot{i}" for i in range(1, count + 1)]
    if isinstance(robots, str) or not isinstance(robots, Sequence):
        raise InvalidArgument(f"robots must be a count or a sequence of names, got {robots!r}")
    names = list(robots)
    if not names or len(names) > MAX_ROBOTS:
        raise InvalidArgument(f"robots must name 1..{MAX_ROBOTS} robots, got {len(names)}")
    # connect_fleet checks each name (before anything starts); a mapping cannot repeat one.
    if len(set(names)) != len(names):
        raise InvalidArgument(f"robot names must differ, got {names!r}")
    return names


@contextlib.asynccontextmanager
async def simulated_fleet(
    robots: int | Sequence[str] = 3,
    *,
    firmware: Literal["real", "document"] = "real",
    targets: Sequence[tuple[float, float]] | None = None,
    navigating: bool = True,
    clock: Clock = "virtual",
    sim_options: Mapping[str, Any] | None = None,
    robot_sim_options: Mapping[str, Mapping[str, Any]] | None = None,
    **options: Any,
) -> AsyncIterator[tuple[Fleet, dict[str, SimulatedDevice]]]:
    """``async with simulated_fleet(3) as (fleet, devices)``: connect_fleet on simulated robots.

    ``robots``: how many (named robot1, robot2, …) or their names; each is a simulated
    robot as simulated_robot() makes it (same ``firmware``, ``targets``, ``navigating``,
    ``sim_options``), ``robot_sim_options[name]`` on top for that one (its ``start_pose``,
    faults …); ``options``: connect_fleet's (connect options for every robot, and its
    own). ``devices[name]`` is that robot's device side; all run on one ``clock``.
    Everything is checked before anything starts (InvalidArgument).
    """
    names = _names(robots)
    per_robot = dict(robot_sim_options or {})
    unknown = sorted(set(per_robot) - set(names))
    if unknown:
        raise InvalidArgument(f"robot_sim_options names robots not in the fleet: {unknown}")
    simulators: dict[str, Simulator] = {}
    fleet_options: dict[str, Any] = {}
    for name in names:
        fleet_options = dict(options)
        extra = per_robot.get(name, {})
        if not isinstance(extra, Mapping):
            raise InvalidArgument(f"robot_sim_options[{name!r}] must be a mapping, got {extra!r}")
        simulators[name] = build_simulator(
            firmware=firmware, targets=targets, navigating=navigating, clock=clock,
            sim_options={**(sim_options or {}), **extra}, options=fleet_options,
        )  # fmt: skip
    virtual = VirtualClock.install() if clock == "virtual" else None
    try:
        async with contextlib.AsyncExitStack() as stack:
            for simulator in simulators.values():
                await stack.enter_async_context(simulator)
            devices = {name: SimulatedDevice(sim, virtual) for name, sim in simulators.items()}
            ports = {name: sim.url for name, sim in simulators.items()}
            async with connect_fleet(ports, **fleet_options) as fleet:
                yield fleet, devices
    finally:
        if virtual is not None:
            virtual.release()
