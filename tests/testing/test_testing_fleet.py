"""simulated_fleet(): connect_fleet on simulated robots, each with its own device side."""

from __future__ import annotations

import asyncio
from typing import Any

import pytest

from galileo_async import LinkState
from galileo_async.errors import InvalidArgument
from galileo_async.protocol import commands as c
from galileo_async.robot.runtime import OPEN_ROBOTS
from galileo_async.testing import VirtualClock, simulated_fleet
from tests.support.cancel_ways import WAYS, stop_waiting


async def test_robots_are_named_and_each_device_is_its_own_robot() -> None:
    async with simulated_fleet(3) as (fleet, devices):
        assert list(fleet) == ["robot1", "robot2", "robot3"]
        assert list(devices) == ["robot1", "robot2", "robot3"]
        assert {fleet.state(name) for name in fleet} == {LinkState.UP}
        robot2 = fleet.get("robot2")
        assert robot2 is not None
        result = await robot2.goto(4)
        assert result.target_id == 4
        assert devices["robot2"].received(c.Goto) == [c.Goto(4)]
        assert devices["robot1"].commands == []
        assert devices["robot3"].commands == []
        assert devices["robot2"].pose.x == pytest.approx(-4.0, abs=0.3)


async def test_names_and_per_robot_options() -> None:
    options = {"b": {"start_pose": (2.0, 1.0, 0.0)}}
    async with simulated_fleet(["a", "b"], robot_sim_options=options) as (fleet, devices):
        assert list(fleet) == ["a", "b"]
        assert (devices["a"].pose.x, devices["a"].pose.y) == (0.0, 0.0)
        assert (devices["b"].pose.x, devices["b"].pose.y) == (2.0, 1.0)
        robot_b = fleet.get("b")
        assert robot_b is not None
        status = await robot_b.wait_until(lambda s: s.current_pose_x is not None, timeout=5)
        assert status.current_pose_x == pytest.approx(2.0)


async def test_one_robot_drops_the_others_stay_up() -> None:
    async with simulated_fleet(3) as (fleet, devices):
        devices["robot3"].drop_link()
        await devices["robot3"].advance(2.0)
        assert [fleet.state(name) for name in fleet] == [
            LinkState.UP, LinkState.UP, LinkState.LOST,
        ]  # fmt: skip
        devices["robot3"].restore_link()
        robot3 = fleet.get("robot3")
        assert robot3 is not None
        await robot3.wait_link(LinkState.UP, timeout=30)
        assert [fleet.state(name) for name in fleet] == [LinkState.UP] * 3


async def test_a_fleet_goal_on_every_robot_takes_virtual_time_only() -> None:
    loop = asyncio.get_running_loop()
    async with simulated_fleet(4) as (fleet, devices):
        began = loop.time()
        robots = [fleet.get(name) for name in fleet]
        results = await asyncio.gather(*(r.goto(i) for i, r in enumerate(robots) if r))
        assert [r.target_id for r in results] == [0, 1, 2, 3]
        assert loop.time() - began > 3.0  # the trips took robot time …
        assert all(device.time > 3.0 for device in devices.values())


@pytest.mark.parametrize(
    ("robots", "extra", "message"),
    [
        (0, {}, "robots must be in 1..1000"),
        (True, {}, "robots must be a count or a sequence"),
        ("ab", {}, "robots must be a count or a sequence"),
        ([], {}, "robots must name 1..1000"),
        (["a", "a"], {}, "must differ"),
        (["a", ""], {}, "non-empty strings"),
        (2, {"robot_sim_options": {"robot9": {}}}, "not in the fleet"),
        (2, {"robot_sim_options": {"robot1": 5}}, "must be a mapping"),
        (2, {"robot_sim_options": {"robot1": {"seed": "x"}}}, "seed must be an int"),
        (2, {"clock": "wall"}, "clock must be"),
        (2, {"sim_options": {"speed": 5}}, "speed"),
    ],
)
async def test_bad_arguments(robots: Any, extra: dict[str, Any], message: str) -> None:
    before = set(OPEN_ROBOTS)
    with pytest.raises(InvalidArgument, match=message):
        async with simulated_fleet(robots, **extra):
            pytest.fail("started")
    assert set(OPEN_ROBOTS) == before
    assert VirtualClock.of() is None


@pytest.mark.parametrize("how", WAYS)
async def test_cancelled_every_way_leaves_nothing(how: str) -> None:
    before = set(OPEN_ROBOTS)

    async def run() -> None:
        async with simulated_fleet(2) as (fleet, _):
            robot = fleet.get("robot1")
            assert robot is not None
            await robot.goto(1, timeout=None)
            await asyncio.Event().wait()

    await stop_waiting(how, run, after=30.0)
    assert set(OPEN_ROBOTS) == before
    assert VirtualClock.of() is None
