"""ros:// reads the map's target count from /galileo/goal_num (real rosmaster parameters)."""

from __future__ import annotations

from collections.abc import AsyncIterator
from pathlib import Path
from typing import Any

import pytest

from galileo_async.errors import GoalAborted, GoalRejected, InvalidArgument, NotReady
from galileo_async.robot import connect
from galileo_async.ros import GOAL_NUM_PARAM
from galileo_async.ros.xmlrpc import xmlrpc_call
from tests.support.ros_support import RobotNode, RosMaster

pytestmark = pytest.mark.timeout(60)

# The robot node's map: five targets.
TARGETS = "1,0;0,1;-1,0;0,-1;2,0"


@pytest.fixture
async def master(tmp_path: Path) -> AsyncIterator[RosMaster]:
    async with RosMaster.running(tmp_path) as master:
        yield master


async def set_param(master: RosMaster, value: Any) -> None:
    uri = f"http://127.0.0.1:{master.port}/"
    code, message, _ = await xmlrpc_call(uri, "setParam", "/test", GOAL_NUM_PARAM, value, timeout=2)
    assert code == 1, message


async def test_goto_point_works_without_map_targets(master: RosMaster) -> None:
    # The node keeps goal_num as the vendor's navigation node does: the string "5".
    node = RobotNode.running(master, "--targets", TARGETS, "--goal-num")
    async with node, connect(master.url) as robot:
        assert robot.map_targets == 5
        await robot.start_navigation(timeout=10)
        result = await robot.goto_point(1.5, -0.5, timeout=10)
        assert result.target_id == 5
        pose = robot.status.pose if robot.status else None
        assert pose is not None
        assert (pose.x, pose.y) == pytest.approx((1.5, -0.5), abs=1e-3)


async def test_an_int_goal_num_is_read_and_map_targets_given_wins(master: RosMaster) -> None:
    await set_param(master, 5)
    async with RobotNode.running(master, "--targets", TARGETS):
        async with connect(master.url) as robot:
            assert robot.map_targets == 5
        async with connect(master.url, map_targets=3) as robot:
            assert robot.map_targets == 3


@pytest.mark.parametrize("value", ["abc", "", 300, -1, True, 2.5, [5]])
async def test_a_goal_num_that_is_not_a_count_is_ignored(master: RosMaster, value: Any) -> None:
    await set_param(master, value)
    async with RobotNode.running(master, "--targets", TARGETS), connect(master.url) as robot:
        assert robot.map_targets is None


async def test_without_goal_num_goto_point_says_how_to_give_the_count(master: RosMaster) -> None:
    async with RobotNode.running(master, "--targets", TARGETS), connect(master.url) as robot:
        assert robot.map_targets is None
        await robot.start_navigation(timeout=10)
        with pytest.raises(NotReady, match="goal_num"):
            await robot.goto_point(1.0, 1.0, timeout=10)


async def test_dynamic_targets_present_at_connect_make_goto_point_fail_safely(
    master: RosMaster,
) -> None:
    # goal_num counts the dynamic targets too (docs/ros.md, limits): one left by an earlier
    # goto_point makes the count one too high. The id the driver computes is then past the
    # robot's last target, so the goal is rejected; the robot never drives to a wrong one.
    async with RobotNode.running(master, "--targets", TARGETS, "--goal-num"):
        async with connect(master.url) as robot:
            await robot.start_navigation(timeout=10)
            await robot.goto_point(1.0, 1.0, timeout=10)
        async with connect(master.url) as robot:
            assert robot.map_targets == 6
            with pytest.raises(GoalRejected):
                await robot.goto_point(0.5, 0.5, timeout=10)
        # A map_targets that contradicts goal_num is refused, even the right one: the driver
        # cannot tell a left dynamic target from a wrong count. Reset, then reconnect.
        async with connect(master.url, map_targets=5) as robot:
            with pytest.raises(InvalidArgument, match="reset_targets"):
                await robot.goto_point(0.5, 0.5, timeout=10)
            await robot.reset_targets()
        async with connect(master.url) as robot:
            assert robot.map_targets == 5
            assert (await robot.goto_point(0.5, 0.5, timeout=10)).target_id == 5


async def test_a_map_targets_that_contradicts_goal_num_is_refused_before_anything_is_sent(
    master: RosMaster,
) -> None:
    node = RobotNode.running(master, "--targets", TARGETS, "--goal-num")
    async with node, connect(master.url, map_targets=3) as robot:
        await robot.start_navigation(timeout=10)
        sent = robot.link.commands_sent
        with pytest.raises(InvalidArgument, match="map_targets=3 contradicts the 5 targets"):
            await robot.goto_point(1.5, -0.5, timeout=10)
        assert robot.link.commands_sent == sent


async def test_without_goal_num_a_too_small_map_targets_fails_at_the_end_pose(
    master: RosMaster,
) -> None:
    # No goal_num: the link cannot tell. Goal 3 is the map's (0, -1), not (1.5, -0.5).
    node = RobotNode.running(master, "--targets", TARGETS)
    async with node, connect(master.url, map_targets=3) as robot:
        await robot.start_navigation(timeout=10)
        with pytest.raises(GoalAborted, match="map_targets") as caught:
            await robot.goto_point(1.5, -0.5, timeout=10)
        assert caught.value.target_id == 3
        assert caught.value.distance == pytest.approx(1.58, abs=0.01)
