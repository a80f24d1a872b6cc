"""Robot.stop() over every link kind the simulator serves: a serial port (pty), socket://,
udp:// and http://, for each kind of motion; the simulator's own state is the witness.

ros:// is covered in test_ros_robot.py (a real ROS 1 master and robot node).
"""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import AsyncIterator
from typing import Any

import pytest

import galileo_async as galileo
from galileo_async import CommandSuperseded, GoalCancelled, StopReport
from galileo_async.models import StatusLayout, TargetStatus
from galileo_async.protocol import StartPatrol
from galileo_async.sim import SimState, Simulator
from tests.links.test_http_link import http_of
from tests.support.sim_integration import FAR, MAP_TARGETS, SPEED, TARGETS, WAIT, Mode, robot_on_sim

#: The serial-protocol links: a pty as a serial port, socket:// and udp://.
SERIAL_LINKS = {
    "pty": Mode("real", StatusLayout.V2, "pty"),
    "tcp": Mode("real", StatusLayout.V2, "tcp"),
    "udp": Mode("real", StatusLayout.UDP_V2, "udp"),
}
LINKS = (*SERIAL_LINKS, "http")


@contextlib.asynccontextmanager
async def robot_on(link: str) -> AsyncIterator[tuple[Simulator, galileo.Robot]]:
    """A Simulator and a Robot connected over ``link``, navigation open."""
    if link in SERIAL_LINKS:
        async with robot_on_sim(SERIAL_LINKS[link]) as pair:
            yield pair
        return
    async with Simulator(speed=SPEED, targets=TARGETS) as sim:
        face = await sim.serve_http()
        url = f"http://127.0.0.1:{face.address[1]}?ws_port={face.ws_address[1]}"
        async with galileo.connect(url, map_targets=MAP_TARGETS) as robot:
            await robot.start_navigation(timeout=WAIT)
            yield sim, robot


def standing(state: SimState) -> bool:
    """The simulated robot's wheels stand still, no goal runs and no patrol."""
    status = state.status
    return (
        status.current_speed_x == 0.0
        and status.current_speed_theta == 0.0
        and status.control_speed_x == 0.0
        and status.control_speed_theta == 0.0
        and not status.goal_active
        and not status.patrolling
    )


async def stands(robot: galileo.Robot, sim: Simulator) -> None:
    """Wait, frame by frame, until the simulator shows the robot standing; then 1 s more."""
    state = sim.state
    await robot.wait_until(lambda _status: standing(state), timeout=WAIT)
    start = state.time
    await robot.wait_until(lambda _status: state.time >= start + 1.0, timeout=WAIT)
    assert standing(state)  # and it stays so


async def driving(robot: galileo.Robot, sim: Simulator) -> None:
    """Wait until the simulator shows the robot driving."""
    state = sim.state
    await robot.wait_until(lambda _s: abs(state.status.current_speed_x or 0.0) > 0.1,
                           timeout=WAIT)  # fmt: skip


async def halted(task: asyncio.Task[Any], error: type[Exception]) -> Exception:
    """``task`` ended with ``error`` naming stop()."""
    with pytest.raises(error) as info:
        await asyncio.wait_for(task, WAIT)
    exc = info.value
    by = getattr(exc, "cancelled_by", None) or getattr(exc, "superseded_by", None)
    assert by == "stop()", exc
    return exc


@pytest.mark.parametrize("link", LINKS)
async def test_stop_cancels_a_goal(link: str) -> None:
    async with robot_on(link) as (sim, robot):
        task = asyncio.ensure_future(robot.goto(FAR, timeout=WAIT))
        await driving(robot, sim)
        report = await robot.stop()
        await halted(task, GoalCancelled)
        assert report.goal == FAR
        await stands(robot, sim)


@pytest.mark.parametrize("link", LINKS)
async def test_stop_ends_a_patrol_another_host_started(link: str) -> None:
    async with robot_on(link) as (sim, robot):
        sim.model.submit(StartPatrol())
        await driving(robot, sim)
        report = await robot.stop()
        assert report.patrol
        assert report.goal is not None
        await stands(robot, sim)


@pytest.mark.parametrize("link", LINKS)
async def test_stop_ends_a_drive_session(link: str) -> None:
    async with robot_on(link) as (sim, robot), robot.drive(0.5, 0.0) as session:
        await driving(robot, sim)
        report = await robot.stop()
        assert not session.active
        assert report.drive
        with pytest.raises(CommandSuperseded):
            session.set(linear=0.2)
        await stands(robot, sim)


@pytest.mark.parametrize("link", ["tcp", "udp"])
async def test_stop_ends_turn_to(link: str) -> None:
    async with robot_on(link) as (sim, robot):
        task = asyncio.ensure_future(robot.turn_to(179.0, timeout=WAIT))
        state = sim.state
        await robot.wait_until(lambda _s: abs(state.status.current_speed_theta or 0.0) > 0.1,
                               timeout=WAIT)  # fmt: skip
        await robot.stop()
        await halted(task, CommandSuperseded)
        await stands(robot, sim)


@pytest.mark.parametrize("link", ["pty", "http"])
async def test_stop_cancels_a_paused_goal(link: str) -> None:
    async with robot_on(link) as (sim, robot):
        task = asyncio.ensure_future(robot.goto(FAR, timeout=WAIT))
        await driving(robot, sim)
        # Over http:// the robot's status shows a nav task up to 1 s after it starts.
        await robot.wait_until(lambda s: s.target_status == TargetStatus.WORKING, timeout=WAIT)
        await robot.pause()
        report = await robot.stop()
        assert report.goal == FAR
        await halted(task, GoalCancelled)
        await stands(robot, sim)


async def test_stop_ends_goto_pose_and_its_task_over_http() -> None:
    async with Simulator(speed=SPEED, targets=TARGETS) as sim:
        face = await sim.serve_http()
        url = f"http://127.0.0.1:{face.address[1]}?ws_port={face.ws_address[1]}"
        async with galileo.connect(url, map_targets=MAP_TARGETS) as robot:
            await robot.start_navigation(timeout=WAIT)
            task = asyncio.ensure_future(http_of(robot).goto_pose(-25.0, 0.0, 0.0, timeout=WAIT))
            await driving(robot, sim)
            report = await robot.stop()
            error = await halted(task, GoalCancelled)
            assert isinstance(error, GoalCancelled)
            assert error.target_id == -2
            assert report.task is not None
            assert report.task in str(error)
            assert f"task {report.task} stopped" in str(report)
            await stands(robot, sim)
            assert face.tasks[report.task]["state"] == "CANCELLED"


@pytest.mark.parametrize("link", LINKS)
async def test_stop_with_nothing_moving_returns_at_once(link: str) -> None:
    async with robot_on(link) as (sim, robot):
        report = await robot.stop()
        assert report == StopReport(status=report.status)
        assert standing(sim.state)
