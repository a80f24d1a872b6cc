"""Fleet.run_missions: every robot's mission at once; the first user stop stops them all."""

from __future__ import annotations

import asyncio
from typing import Any

import pytest

from galileo_async import InvalidArgument, Robot
from galileo_async.missions import Mission, MissionEvent, MissionRejected, StepStarted
from galileo_async.robot.stopping import in_motion
from galileo_async.testing import simulated_fleet
from tests.support.cancel_ways import WAYS, stop_waiting

pytestmark = pytest.mark.timeout(60)


def mission(name: str, *steps: Any) -> Mission:
    return Mission.model_validate({"mission": name, "steps": list(steps)})


PATROL = mission("patrol", {"loop": {"count": "forever", "steps": [{"goto": 1}, {"goto": 2}]}})


def still(robot: Robot) -> bool:
    status = robot.status
    return status is not None and in_motion(status) == ()


async def test_each_robot_runs_its_own_mission_at_once() -> None:
    missions = {
        "robot1": mission("one", {"goto": 1}, {"dwell": 2}),
        "robot2": mission("two", {"goto": 2}),
        "robot3": mission("three", {"loop": {"count": 2, "steps": [{"goto": 3}, {"goto": 0}]}}),
    }
    seen: list[tuple[str, MissionEvent]] = []
    async with simulated_fleet(3) as (fleet, _):
        loop = asyncio.get_running_loop()
        start = loop.time()
        reports = await fleet.run_missions(
            missions, on_progress=lambda name, event: seen.append((name, event))
        )
        took = loop.time() - start
    assert list(reports) == ["robot1", "robot2", "robot3"]
    assert {name: r.ending for name, r in reports.items()} == dict.fromkeys(missions, "completed")
    assert [r.mission for r in reports.values()] == ["one", "two", "three"]
    assert took < sum(r.ended - r.started for r in reports.values())  # at once, not in turn
    first = [name for name, event in seen if isinstance(event, StepStarted)][:3]
    assert sorted(first) == ["robot1", "robot2", "robot3"]


async def test_fleet_stop_ends_every_mission_stopped() -> None:
    async with simulated_fleet(3) as (fleet, _):
        running = asyncio.ensure_future(fleet.run_missions(dict.fromkeys(fleet, PATROL)))
        await asyncio.sleep(5)
        await fleet.stop()
        reports = await running
        assert all(still(fleet[name]) for name in fleet)
    assert {r.ending for r in reports.values()} == {"stopped"}


async def test_one_robots_stop_stops_the_whole_fleet() -> None:
    async with simulated_fleet(3) as (fleet, _):
        running = asyncio.ensure_future(fleet.run_missions(dict.fromkeys(fleet, PATROL)))
        await asyncio.sleep(5)
        await fleet["robot2"].stop()
        reports = await running
        assert all(still(fleet[name]) for name in fleet)
    assert {r.ending for r in reports.values()} == {"stopped"}
    assert reports["robot2"].stopped_by == "stop()"


@pytest.mark.parametrize("how", WAYS)
async def test_cancelling_the_fleet_run_stops_every_robot(how: str) -> None:
    async with simulated_fleet(2) as (fleet, _):

        async def run() -> None:
            await fleet.run_missions(dict.fromkeys(fleet, PATROL))

        await stop_waiting(how, run, 4.0)
        assert all(still(fleet[name]) for name in fleet)


async def test_every_mission_is_checked_before_any_robot_moves() -> None:
    bad = mission("bad", {"say": "hello"})
    async with simulated_fleet(2) as (fleet, devices):
        with pytest.raises(MissionRejected) as info:
            await fleet.run_missions({"robot1": PATROL, "robot2": bad})
        assert all(device.commands == [] for device in devices.values())
        with pytest.raises(InvalidArgument, match="no robot named 'robot9'"):
            await fleet.run_missions({"robot9": PATROL})
    assert info.value.problems == ["robot2: steps[0]: say needs an http:// or https:// link"]
