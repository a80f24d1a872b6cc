"""Robot.stop() halts every motion, whoever started it, on the virtual clock (sim://).

The simulator's own model is the witness: after stop() no goal runs, no patrol, and the
wheels stand still. Every call awaiting motion ends at once (no simulated time passes)
with an error naming stop().
"""

from __future__ import annotations

import asyncio
from collections.abc import AsyncIterator, Awaitable, Callable
from typing import Any

import pytest

from galileo_async import (
    ChargeStatus,
    CommandSuperseded,
    GalileoConnectionError,
    GoalCancelled,
    InvalidArgument,
    Robot,
    StopReport,
    StopUnconfirmed,
    TargetStatus,
)
from galileo_async import events as ev
from galileo_async.protocol import Cancel, Goto, Stop, StopPatrol
from galileo_async.robot.runtime import OPEN_ROBOTS
from galileo_async.testing import SimulatedDevice, simulated_robot
from tests.support.cancel_ways import WAYS, stop_waiting

#: A map with one target 30 m ahead (a long trip) and two near ones (patrol legs).
TARGETS = ((30.0, 0.0), (2.0, 0.0), (0.0, 2.0))
FAR = 0
#: Virtual seconds: long enough for any stop to show, short beside the 37 s trip.
WAIT = 20.0


def standing(device: SimulatedDevice) -> bool:
    """The simulated robot's wheels stand still, no goal runs and no patrol."""
    model = device.simulator.model
    return (
        model.current_v == 0.0
        and model.current_w == 0.0
        and model.control_v == 0.0
        and model.control_w == 0.0
        and model.target_status not in (1, 2)
        and model.loop_status == 0
    )


def moving(device: SimulatedDevice) -> bool:
    """The simulated robot's wheels turn."""
    model = device.simulator.model
    return abs(model.current_v) > 0.1 or abs(model.current_w) > 0.1


async def started(robot: Robot, call: Callable[[], Awaitable[Any]]) -> asyncio.Task[Any]:
    """Start ``call()`` as a task and return once the robot moves."""
    task: asyncio.Task[Any] = asyncio.ensure_future(call())
    await robot.wait_until(lambda s: abs(s.current_speed_x or 0.0) > 0.1
                           or abs(s.current_speed_theta or 0.0) > 0.1, timeout=WAIT)  # fmt: skip
    assert not task.done()
    return task


async def stopped_at_once(
    robot: Robot, device: SimulatedDevice, task: asyncio.Task[Any]
) -> tuple[StopReport, BaseException]:
    """Call stop(); the task ends before any simulated time passes; the robot stands."""
    called_at = device.time
    stopping = asyncio.ensure_future(robot.stop())
    await asyncio.wait((task,))
    assert device.time == called_at  # at once
    error = task.exception()
    assert error is not None
    report = await stopping
    assert standing(device)
    return report, error


@pytest.fixture
async def sim(
    request: pytest.FixtureRequest,
) -> AsyncIterator[tuple[Robot, SimulatedDevice]]:
    firmware = getattr(request, "param", "real")
    async with simulated_robot(firmware=firmware, targets=TARGETS) as pair:
        yield pair


async def test_stop_during_goto_cancels_the_goal_and_goto_raises_at_once(
    sim: tuple[Robot, SimulatedDevice],
) -> None:
    robot, device = sim
    events = robot.events()
    task = await started(robot, lambda: robot.goto(FAR))
    report, error = await stopped_at_once(robot, device, task)
    assert isinstance(error, GoalCancelled)
    assert error.cancelled_by == "stop()"
    assert not error.preempted
    assert "stop()" in str(error)
    assert (report.goal, report.patrol, report.drive, report.moving) == (FAR, False, False, True)
    assert str(report) == f"goal {FAR} cancelled, speed zeroed"
    assert report.status is not None
    assert not report.status.goal_active
    assert device.received(Cancel, Stop) == [Cancel(), Stop(100)]
    # events() names the end a cancel, not a planner abort.
    ends = []
    async for event in events:
        if isinstance(event, ev.GoalEvent) and not isinstance(event, ev.GoalAccepted):
            ends.append(event)
            break
    assert isinstance(ends[0], ev.GoalCancelledEvent)
    await device.advance(5.0)
    assert standing(device)  # stays stopped


async def test_stop_during_goto_point_raises_goal_cancelled(
    sim: tuple[Robot, SimulatedDevice],
) -> None:
    robot, device = sim
    task = await started(robot, lambda: robot.goto_point(-20.0, 0.0))
    _report, error = await stopped_at_once(robot, device, task)
    assert isinstance(error, GoalCancelled)
    assert error.cancelled_by == "stop()"


async def test_stop_cancels_a_paused_goal(sim: tuple[Robot, SimulatedDevice]) -> None:
    robot, device = sim
    task = await started(robot, lambda: robot.goto(FAR))
    await robot.pause()
    assert device.simulator.model.target_status == TargetStatus.PAUSED
    report = await robot.stop()
    assert report.goal == FAR
    assert standing(device)
    with pytest.raises(GoalCancelled):
        await task


async def test_stop_cancels_a_goal_another_host_started(
    sim: tuple[Robot, SimulatedDevice],
) -> None:
    robot, device = sim
    device.simulator.model.submit(Goto(FAR))  # as the robot's own tablet would
    await robot.wait_until(lambda s: (s.current_speed_x or 0.0) > 0.1, timeout=WAIT)
    report = await robot.stop()
    assert report.goal == FAR
    assert report.moving
    assert standing(device)


async def test_stop_ends_a_patrol_and_its_leg(sim: tuple[Robot, SimulatedDevice]) -> None:
    robot, device = sim
    await robot.start_patrol()
    await robot.wait_until(lambda s: (s.current_speed_x or 0.0) > 0.1, timeout=WAIT)
    report = await robot.stop()
    assert report.patrol
    assert report.goal is not None
    # The patrol is stopped before the goal is cancelled: it cannot start its next leg.
    assert device.received(StopPatrol, Cancel, Stop) == [StopPatrol(), Cancel(), Stop(100)]
    assert standing(device)
    await device.advance(10.0)  # the dwell passes: no next leg
    assert standing(device)


@pytest.mark.parametrize("sim", ["document"], indirect=True)
async def test_a_patrol_the_firmware_does_not_stop_is_reported(
    sim: tuple[Robot, SimulatedDevice],
) -> None:
    # The document's firmware ignores 'm' 6: stop() says so instead of returning.
    robot, _device = sim
    await robot.start_patrol()
    await robot.wait_until(lambda s: s.patrolling, timeout=WAIT)
    with pytest.raises(StopUnconfirmed) as info:
        await robot.stop(timeout=3.0)
    assert "patrol" in info.value.unconfirmed
    assert "patrol" in str(info.value)


async def test_stop_ends_a_drive_session(sim: tuple[Robot, SimulatedDevice]) -> None:
    robot, device = sim
    async with robot.drive(0.5, 0.0) as session:
        await robot.wait_until(lambda s: (s.current_speed_x or 0.0) > 0.4, timeout=WAIT)
        report = await robot.stop(brake=50)
        assert not session.active
        with pytest.raises(CommandSuperseded) as info:
            session.set(linear=0.3)
        assert info.value.superseded_by == "stop()"
    assert report.drive
    assert report.moving
    assert report.goal is None
    assert str(report) == "drive ended, speed zeroed"
    assert device.received(Stop)[-1] == Stop(50)
    assert standing(device)


async def test_stop_ends_turn_to_at_once(sim: tuple[Robot, SimulatedDevice]) -> None:
    robot, device = sim
    task = await started(robot, lambda: robot.turn_to(179.0))
    report, error = await stopped_at_once(robot, device, task)
    assert isinstance(error, CommandSuperseded)
    assert error.superseded_by == "stop()"
    assert report.drive


@pytest.mark.parametrize("sim", ["document"], indirect=True)
async def test_stop_ends_rotate_to_at_once(sim: tuple[Robot, SimulatedDevice]) -> None:
    robot, device = sim
    task = await started(robot, lambda: robot.rotate_to(179.0))
    _report, error = await stopped_at_once(robot, device, task)
    assert isinstance(error, CommandSuperseded)
    assert error.superseded_by == "stop()"


async def test_turn_to_updates_the_speed_at_the_session_rate(
    sim: tuple[Robot, SimulatedDevice],
) -> None:
    # 30 frames a second, but 5 speed updates (f/c pairs at most) a second.
    robot, device = sim
    start = device.time
    await robot.turn_to(170.0, timeout=WAIT)
    elapsed = device.time - start
    speeds = [c for c in device.commands if c.at >= start and type(c.command).__name__ in
              ("Forward", "Backward", "TurnLeft", "TurnRight")]  # fmt: skip
    assert elapsed > 1.0
    assert len(speeds) <= 2 * (5 * elapsed + 2)


async def test_stop_with_nothing_moving_sends_the_stop_and_says_so(
    sim: tuple[Robot, SimulatedDevice],
) -> None:
    robot, device = sim
    report = await robot.stop()
    assert report == StopReport(status=report.status)
    assert str(report) == "nothing was moving"
    assert device.received() == [Cancel(), Stop(100)]


async def test_zero_speed_writes_one_stop_and_a_goal_drives_on(
    sim: tuple[Robot, SimulatedDevice],
) -> None:
    robot, device = sim
    task = await started(robot, lambda: robot.goto(FAR))
    await robot.zero_speed()
    await device.advance(3.0)
    assert moving(device)  # the navigation stack overrides a teleop stop
    assert not task.done()
    await robot.stop()
    with pytest.raises(GoalCancelled):
        await task


async def test_a_robot_that_does_not_show_the_stop_raises_stop_unconfirmed(
    sim: tuple[Robot, SimulatedDevice],
) -> None:
    robot, device = sim
    task = await started(robot, lambda: robot.goto(FAR, cancel_on_exit=False))
    device.freeze()  # a dead navigation stack: the status shows the goal working
    with pytest.raises(StopUnconfirmed) as info:
        await robot.stop(timeout=2.0)
    assert info.value.unconfirmed == ("goal", "speed")
    assert info.value.status is not None
    assert "goal, speed" in str(info.value)
    with pytest.raises(GoalCancelled):
        await task


async def test_stop_checks_its_arguments_before_anything(
    sim: tuple[Robot, SimulatedDevice],
) -> None:
    robot, device = sim
    task = await started(robot, lambda: robot.goto(FAR))
    for bad in ({"brake": 101}, {"brake": -1}, {"timeout": -1.0}):
        with pytest.raises(InvalidArgument):
            await robot.stop(**bad)
    assert not task.done()  # nothing was stopped
    assert device.received(Cancel, Stop) == []
    await robot.stop()
    with pytest.raises(GoalCancelled):
        await task


async def test_stop_on_a_closed_robot_is_a_connection_error() -> None:
    async with simulated_robot() as (robot, _device):
        pass
    with pytest.raises(GalileoConnectionError):
        await robot.stop()


@pytest.mark.parametrize("how", WAYS)
async def test_a_stop_whose_caller_stops_waiting_still_stops_the_robot(how: str) -> None:
    robots = set(OPEN_ROBOTS)
    async with simulated_robot(targets=TARGETS) as (robot, device):
        task = await started(robot, lambda: robot.goto(FAR))
        # Stopped waiting before its first write: the whole stop is written all the same.
        await stop_waiting(how, robot.stop, after=0.0)
        with pytest.raises(GoalCancelled):
            await task
        await robot.wait_until(lambda s: not s.goal_active, timeout=WAIT)
        await device.advance(3.0)
        assert standing(device)
        assert device.received(Cancel, Stop) == [Cancel(), Stop(100)]
    assert set(OPEN_ROBOTS) <= robots


async def test_stop_from_another_task_ends_the_drive_block_at_once(
    sim: tuple[Robot, SimulatedDevice],
) -> None:
    robot, device = sim
    inside: list[str] = []

    async def drive() -> None:
        async with robot.drive(0.5, 0.0):
            inside.append("entered")
            await asyncio.sleep(3600)  # the application's own wait
            inside.append("woke")  # never: the stop ends the body

    task = await started(robot, drive)
    report, error = await stopped_at_once(robot, device, task)
    assert isinstance(error, CommandSuperseded)
    assert error.superseded_by == "stop()"
    assert "drive" in str(error)
    assert inside == ["entered"]
    assert report.drive


async def test_a_user_stop_from_inside_the_drive_block_does_not_cancel_its_caller(
    sim: tuple[Robot, SimulatedDevice],
) -> None:
    robot, device = sim
    async with robot.drive(0.5, 0.0) as session:
        await robot.wait_until(lambda s: (s.current_speed_x or 0.0) > 0.4, timeout=WAIT)
        report = await robot.stop()  # returns: the block's own task called it
        assert not session.active
        await asyncio.sleep(0)
    assert report.drive
    assert standing(device)


async def test_close_right_after_a_stop_in_another_task_still_writes_the_whole_stop() -> None:
    async with simulated_robot(targets=TARGETS) as (robot, device):
        task = await started(robot, lambda: robot.goto(FAR))
        stopping = asyncio.ensure_future(robot.stop())
        await asyncio.sleep(0)  # the stop has started its writes
        await robot.close()
        assert device.received(Cancel, Stop) == [Cancel(), Stop(100)]
        with pytest.raises(GoalCancelled):
            await task
        with pytest.raises(GalileoConnectionError):  # closed: nothing can confirm it
            await stopping


async def test_stop_ends_the_drive_to_the_dock(sim: tuple[Robot, SimulatedDevice]) -> None:
    robot, device = sim
    device.place(1.0, 0.5, 0.0)  # near the dock, not on it
    await robot.start_charging()
    await robot.wait_until(lambda s: abs(s.current_speed_x or 0.0) > 0.05
                           or abs(s.current_speed_theta or 0.0) > 0.05, timeout=WAIT)  # fmt: skip
    report = await robot.stop()
    assert report.docking
    assert "docking stopped" in str(report)
    assert device.status.charge_status == ChargeStatus.FREE
    await device.advance(5.0)
    assert standing(device)
