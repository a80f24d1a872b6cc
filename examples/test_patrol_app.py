"""Tests of examples/patrol_app.py on a simulated robot, with galileo_async's pytest plugin.

Install galileo-async with the extra [testing] (README's Install), then:
pytest examples/test_patrol_app.py
Each test gets a fresh simulated robot (navigation open, six targets) on a virtual clock:
a patrol of minutes takes milliseconds, and the test fails if it leaves anything running.
"""

from __future__ import annotations

import asyncio

import pytest
from patrol_app import patrol

from galileo_async import Robot
from galileo_async.protocol import Cancel, Goto, Stop
from galileo_async.testing import SimulatedDevice

# Works whatever the project's asyncio_mode: strict (pytest-asyncio's default) needs it.
pytestmark = pytest.mark.asyncio


def no_output(message: str) -> None:
    """The patrol's reports, not printed."""


async def test_visits_every_target_in_order(
    galileo_robot: Robot, galileo_device: SimulatedDevice
) -> None:
    report = await patrol(galileo_robot, [1, 2, 3], laps=2, on_event=no_output)
    assert report.visited == [1, 2, 3, 1, 2, 3]
    assert report.laps == 2
    assert report.stopped is None
    assert galileo_device.received(Goto) == [Goto(1), Goto(2), Goto(3)] * 2


async def test_a_refused_target_is_skipped(
    galileo_robot: Robot, galileo_device: SimulatedDevice
) -> None:
    galileo_device.reject_next_goal()
    events: list[str] = []
    report = await patrol(galileo_robot, [1, 2], on_event=events.append)
    assert (report.visited, report.skipped) == ([2], [1])
    assert events[0] == "target 1 not accepted: skipped"


async def test_a_target_missing_from_the_map_is_skipped(galileo_robot: Robot) -> None:
    report = await patrol(galileo_robot, [1, 42, 2], on_event=no_output)  # six targets: 0-5
    assert (report.visited, report.skipped) == ([1, 2], [42])


async def test_a_planner_abort_is_retried_once(
    galileo_robot: Robot, galileo_device: SimulatedDevice
) -> None:
    galileo_device.abort_next_goal()
    report = await patrol(galileo_robot, [1, 2], on_event=no_output)
    assert report.visited == [1, 2]
    assert report.retries == 1
    assert galileo_device.received(Goto) == [Goto(1), Goto(1), Goto(2)]


@pytest.mark.galileo_sim(sim_options={"planner_abort": 1.0})  # every goal stops short
async def test_a_target_aborted_twice_is_skipped(
    galileo_robot: Robot, galileo_device: SimulatedDevice
) -> None:
    report = await patrol(galileo_robot, [1], on_event=no_output)
    assert (report.visited, report.skipped, report.retries) == ([], [1], 1)
    assert galileo_device.received(Goto) == [Goto(1), Goto(1)]


async def test_a_lost_link_is_waited_for(
    galileo_robot: Robot, galileo_device: SimulatedDevice
) -> None:
    task = asyncio.create_task(patrol(galileo_robot, [1, 2], on_event=no_output))
    await galileo_device.advance(1)  # on its way to target 1
    galileo_device.drop_link()
    await galileo_device.advance(3)
    galileo_device.restore_link()  # the driver's next retry reconnects
    report = await task
    assert report.visited == [1, 2]
    assert report.link_outages == 1
    # Back, the driver cancels the goal the robot drove unwatched; the patrol sends it again.
    assert galileo_device.received() == [Goto(1), Cancel(), Goto(1), Goto(2)]


async def test_a_link_that_stays_down_ends_the_patrol(
    galileo_robot: Robot, galileo_device: SimulatedDevice
) -> None:
    task = asyncio.create_task(patrol(galileo_robot, [1, 2], link_timeout=30, on_event=no_output))
    await galileo_device.advance(1)
    galileo_device.drop_link()
    report = await task  # 30 virtual seconds later
    assert report.stopped == "link lost"
    assert report.visited == []


async def test_a_busy_robot_is_waited_out(
    galileo_robot: Robot, galileo_device: SimulatedDevice
) -> None:
    galileo_device.busy(4)
    await galileo_device.advance(0.1)  # the robot's next frames show it busy
    report = await patrol(galileo_robot, [1], on_event=no_output)
    assert report.visited == [1]
    [goal] = [r for r in galileo_device.commands if r.command == Goto(1)]
    assert goal.at >= 4  # the driver waited: the goal was not sent into the busy period
    assert not goal.busy


@pytest.mark.galileo_sim(progress_timeout=10)
async def test_a_frozen_robot_stops_the_patrol(
    galileo_robot: Robot, galileo_device: SimulatedDevice
) -> None:
    task = asyncio.create_task(patrol(galileo_robot, [1, 2], on_event=no_output))
    await galileo_device.advance(1)
    galileo_device.freeze()  # the navigation stack dies; the link stays fresh
    report = await task
    assert report.stopped == "stalled at 1"
    assert report.visited == []
    # The stalled goal's own cancel, then stop(): cancel and zero speed again.
    assert galileo_device.received(Cancel, Stop) == [Cancel(), Cancel(), Stop()]
    assert galileo_device.received(Goto) == [Goto(1)]  # target 2 never tried


async def test_cancelling_the_patrol_stops_the_robot(
    galileo_robot: Robot, galileo_device: SimulatedDevice
) -> None:
    task = asyncio.create_task(patrol(galileo_robot, [1, 2], laps=None, on_event=no_output))
    await galileo_device.advance(1)
    assert galileo_device.status.target_status == 1  # working: on its way
    task.cancel()
    with pytest.raises(asyncio.CancelledError):
        await task
    await galileo_device.advance(0.5)
    assert galileo_device.received(Cancel) == [Cancel()]
    assert galileo_device.status.target_status == 0  # free: the robot stands
    assert galileo_device.status.current_speed_x == 0
