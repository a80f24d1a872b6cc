"""Robot scenarios over ros:// against a real ROS 1 master and a rospy robot node."""

from __future__ import annotations

import asyncio
import contextlib
import math
from collections.abc import AsyncIterator
from pathlib import Path

import pytest

import galileo_async as galileo
from galileo_async.errors import (
    CommandSuperseded,
    GoalAborted,
    GoalCancelled,
    GoalRejected,
    GoalStalled,
    NotReady,
)
from galileo_async.models import GalileoStatus, StatusLayout, TargetStatus
from galileo_async.robot import Robot, connect
from galileo_async.ros import RosChannel
from tests.support.ros_support import RobotNode, RosMaster

pytestmark = pytest.mark.timeout(60)

# Targets of the robot node's map: four at 1 m, a far one at 6 m for goals that last.
TARGETS = "1,0;0,1;-1,0;0,-1;6,0"
FAR = 4


@pytest.fixture
async def master(tmp_path: Path) -> AsyncIterator[RosMaster]:
    async with RosMaster.running(tmp_path) as master:
        yield master


@pytest.fixture
async def node(master: RosMaster) -> AsyncIterator[RobotNode]:
    async with RobotNode.running(master, "--targets", TARGETS, "--speed", "3") as node:
        yield node


@pytest.fixture
async def robot(master: RosMaster, node: RobotNode) -> AsyncIterator[Robot]:
    async with connect(master.url, map_targets=5, connect_timeout=5.0) as robot:
        yield robot


async def test_goto_arrives_over_ros(robot: Robot) -> None:
    assert robot.status is not None
    assert robot.status.layout == StatusLayout.ROS
    await robot.start_navigation(timeout=10)
    result = await robot.goto(1, timeout=10)
    assert result.target_id == 1
    assert result.distance is not None
    assert abs(result.distance) < 0.01
    pose = robot.status.pose if robot.status else None
    assert pose is not None
    assert math.isclose(pose.x, 0.0, abs_tol=1e-3)
    assert math.isclose(pose.y, 1.0, abs_tol=1e-3)
    assert robot.link.frames > 0
    assert robot.link.commands_sent >= 2


async def test_goto_point_sends_float_payloads_intact(robot: Robot) -> None:
    await robot.start_navigation(timeout=10)
    result = await robot.goto_point(2.0, -1.5, timeout=10)
    assert result.target_id == 5  # after the map's five targets
    pose = robot.status.pose if robot.status else None
    assert pose is not None
    assert (pose.x, pose.y) == pytest.approx((2.0, -1.5), abs=1e-3)


async def test_goto_rejected_keeps_the_id(robot: Robot) -> None:
    await robot.start_navigation(timeout=10)
    await robot.goto(2, timeout=10)
    with pytest.raises(GoalRejected) as caught:
        await robot.goto(9, timeout=10)
    assert caught.value.target_id == 9
    status = robot.status
    assert status is not None
    # Real firmware: the error is -1 and target_num_id is not updated (docs/protocol.md §2.b).
    assert status.target_status == TargetStatus.INVALID
    assert status.target_num_id == 2


async def test_cancel_ends_the_goal(robot: Robot) -> None:
    await robot.start_navigation(timeout=10)
    goal = asyncio.create_task(robot.goto(FAR, timeout=20))
    try:
        await robot.wait_until(
            lambda s: s.target_num_id == FAR and s.target_status == TargetStatus.WORKING,
            timeout=5,
        )
        await robot.cancel(timeout=5)
        with pytest.raises(GoalCancelled) as caught:
            await asyncio.wait_for(goal, 5)
        assert not caught.value.preempted
        assert robot.status is not None
        assert robot.status.target_num_id == -1
    finally:
        goal.cancel()
        await asyncio.gather(goal, return_exceptions=True)


async def test_new_goal_preempts_the_running_one(robot: Robot) -> None:
    await robot.start_navigation(timeout=10)
    first = asyncio.create_task(robot.goto(FAR, timeout=20))
    try:
        await robot.wait_until(
            lambda s: s.target_num_id == FAR and s.target_status == TargetStatus.WORKING,
            timeout=5,
        )
        result = await robot.goto(0, timeout=10)
        assert result.target_id == 0
        with pytest.raises(GoalCancelled) as caught:
            await asyncio.wait_for(first, 5)
        assert caught.value.preempted
        assert caught.value.target_id == FAR
    finally:
        first.cancel()
        await asyncio.gather(first, return_exceptions=True)


async def test_patrol_visits_targets_then_stops(robot: Robot) -> None:
    await robot.start_navigation(timeout=10)
    visited: set[int] = set()
    await robot.start_patrol(timeout=5)
    async with asyncio.timeout(15):
        async for status in robot.statuses():
            if status.target_status == TargetStatus.FREE and status.target_num_id is not None:
                visited.add(status.target_num_id)
            if {0, 1} <= visited:
                break
    await robot.stop_patrol(timeout=5)
    assert robot.status is not None
    assert not robot.status.patrolling
    assert robot.status.navigating


async def test_mapping_round_trip(robot: Robot) -> None:
    await robot.start_navigation(timeout=10)
    with pytest.raises(NotReady):  # mapping needs navigation closed
        await robot.start_mapping(timeout=5)
    await robot.stop_navigation(timeout=5)
    await robot.start_mapping(timeout=5)
    assert robot.status is not None
    assert robot.status.mapping
    assert not robot.status.navigating
    with pytest.raises(NotReady):
        await robot.start_navigation(timeout=5)
    await robot.stop_mapping(timeout=5)
    assert robot.status is not None
    assert not robot.status.mapping


async def test_busy_robot_holds_the_goal_until_free(robot: Robot, node: RobotNode) -> None:
    await robot.start_navigation(timeout=10)
    await node.control("busy 1.0")
    await robot.wait_until(lambda s: s.is_busy, timeout=5)
    loop = asyncio.get_running_loop()
    started = loop.time()
    result = await robot.goto(3, timeout=15)
    assert result.target_id == 3
    assert robot.status is not None
    assert not robot.status.is_busy
    assert loop.time() - started > 0.5  # it waited for busy to end


async def test_older_13_field_status(master: RosMaster) -> None:
    async with (
        RobotNode.running(master, "--version", "13", "--targets", TARGETS),
        galileo.connect(master.url, map_targets=5) as robot,
    ):
        status = robot.status
        assert status is not None
        assert status.layout == StatusLayout.ROS
        # Fields this version lacks are unknown, never zero.
        assert status.map_status is None
        assert status.busy_status is None
        assert status.pose is None
        assert status.gc_status is None
        assert status.power == pytest.approx(12.5)
        assert status.time_stamp is not None
        channel = robot._link.channel
        assert isinstance(channel, RosChannel)
        assert channel.node is not None
        assert channel.node.decoder is not None
        assert len(channel.node.decoder.field_names) == 14
        await robot.start_navigation(timeout=10)
        result = await robot.goto(0, timeout=10)
        assert result.target_id == 0


async def test_pause_and_resume_then_arrive(robot: Robot) -> None:
    await robot.start_navigation(timeout=10)
    goal = asyncio.create_task(robot.goto(FAR, timeout=20))
    try:
        await robot.wait_until(lambda s: s.target_status == TargetStatus.WORKING, timeout=5)
        await robot.pause(timeout=5)
        paused_at = robot.status.pose if robot.status else None
        assert not goal.done()  # paused is not an end
        await robot.resume(timeout=5)
        result = await asyncio.wait_for(goal, 15)
        assert result.target_id == FAR
        assert paused_at is not None
        assert paused_at.x < 6.0
    finally:
        goal.cancel()
        await asyncio.gather(goal, return_exceptions=True)


async def test_planner_abort_is_goal_aborted(robot: Robot, node: RobotNode) -> None:
    await robot.start_navigation(timeout=10)
    goal = asyncio.create_task(robot.goto(FAR, timeout=20))
    try:
        await robot.wait_until(lambda s: s.target_status == TargetStatus.WORKING, timeout=5)
        await node.control("abort")
        with pytest.raises(GoalAborted) as caught:
            await asyncio.wait_for(goal, 5)
        assert caught.value.distance is not None
        assert caught.value.distance > 0.3
    finally:
        goal.cancel()
        await asyncio.gather(goal, return_exceptions=True)


async def test_a_dead_navigation_stack_stalls_the_goal_and_its_cancel_is_the_last_word(
    robot: Robot, node: RobotNode
) -> None:
    await robot.start_navigation(timeout=10)
    goal = asyncio.create_task(robot.goto(FAR, timeout=20, progress_timeout=0.6))
    try:
        await robot.wait_until(lambda s: s.target_status == TargetStatus.WORKING, timeout=5)
        await node.control("freeze")  # the same status again and again, with a live header
        with pytest.raises(GoalStalled) as caught:
            await asyncio.wait_for(goal, 10)
        assert caught.value.target_id == FAR
        assert robot.link.connected  # the link itself stayed fresh all along
        # The stack restarts: the latched last command is what it executes, and that is
        # the driver's cancel (i 2), written before GoalStalled was raised.
        await node.control("thaw")
        ended = await robot.wait_until(lambda s: not s.goal_active, timeout=5)
        assert ended.target_num_id == -1  # cancelled (the firmware drops the id), not arrived
    finally:
        goal.cancel()
        await asyncio.gather(goal, return_exceptions=True)


async def test_timeout_around_goto_stops_the_robot(robot: Robot) -> None:
    await robot.start_navigation(timeout=10)
    with pytest.raises(asyncio.TimeoutError):
        await asyncio.wait_for(robot.goto(FAR), 0.5)
    # cancel_on_exit: i 2 went out over /galileo/cmds before the timeout was re-raised.
    status = await robot.wait_until(lambda s: not s.goal_active, timeout=5)
    assert status.target_num_id == -1


async def test_a_stop_over_ros_supersedes_drive_and_goal_waiting_out_busy(
    robot: Robot, node: RobotNode
) -> None:
    await robot.start_navigation(timeout=10)
    await node.control("busy 30")
    await robot.wait_until(lambda s: s.is_busy, timeout=5)
    seen: list[GalileoStatus] = []

    async def collect() -> None:
        async for status in robot.statuses():
            seen.append(status)

    collector = asyncio.ensure_future(collect())
    drive = asyncio.ensure_future(robot.forward(30, timeout=15))
    goal = asyncio.ensure_future(robot.goto(FAR, timeout=15))
    await asyncio.sleep(0)  # both reach the busy back-off
    await robot.stop()
    with pytest.raises(CommandSuperseded):
        await asyncio.wait_for(drive, 1.0)
    with pytest.raises(GoalCancelled):
        await asyncio.wait_for(goal, 1.0)
    await node.control("busy 0")
    await robot.forward(10)  # a marker: applied after anything written before it
    await robot.wait_until(lambda s: s.control_speed_x == pytest.approx(0.1), timeout=5)
    await robot.stop()
    collector.cancel()
    with contextlib.suppress(asyncio.CancelledError):
        await collector
    assert seen
    assert not [s for s in seen if s.control_speed_x == pytest.approx(0.3)]
    assert not [s for s in seen if s.target_num_id == FAR]


def _standing(status: GalileoStatus) -> bool:
    return (
        not status.goal_active
        and not status.patrolling
        and abs(status.current_speed_x or 0.0) < 0.01
        and abs(status.control_speed_x or 0.0) < 0.01
    )


async def test_stop_over_ros_cancels_the_goal_and_ends_goto(robot: Robot) -> None:
    await robot.start_navigation(timeout=10)
    goal = asyncio.ensure_future(robot.goto(FAR, timeout=20))
    await robot.wait_until(lambda s: (s.current_speed_x or 0.0) > 0.1, timeout=5)
    report = await robot.stop()
    with pytest.raises(GoalCancelled) as caught:
        await asyncio.wait_for(goal, 1.0)
    assert caught.value.cancelled_by == "stop()"
    assert report.goal == FAR
    assert report.status is not None
    assert _standing(report.status)  # the robot node's own status


async def test_stop_over_ros_ends_the_patrol(robot: Robot) -> None:
    # drive() over ros:// and stop(): test_ros_drive.py (the /cmd_vel listener).
    await robot.start_navigation(timeout=10)
    await robot.start_patrol(timeout=5)
    await robot.wait_until(lambda s: (s.current_speed_x or 0.0) > 0.1, timeout=5)
    report = await robot.stop()
    assert report.patrol
    assert report.status is not None
    assert _standing(report.status)
