"""The simulator's HTTP tasks and status against what the vendor's own code does (VENDOR.md §1).

Sources: BluewhaleRobot/system_monitor, branch noetic (e2502ff),
src/system_monitor/utils/galileo_status_service.py: how /galileo/status shows an HTTP nav task.
"""

from __future__ import annotations

import pytest
from test_http_link import WAIT, navigating, robot_on_http

from galileo_async import GoalAborted, TaskFailed

pytestmark = pytest.mark.timeout(60)


# --- a nav task the planner gave up on ---------------------------------------------------


async def test_a_pose_task_given_up_a_few_centimetres_short_is_an_error() -> None:
    # A 0.1 m goal aborted half way stops about 4 cm short: no arrival, so no COMPLETE.
    async with robot_on_http(planner_abort="next") as (sim, robot, face):
        await navigating(robot)
        with pytest.raises(TaskFailed) as info:
            await robot.goto_pose(0.1, 0.0, timeout=WAIT)
        assert info.value.state == "ERROR"
        assert sim.state.pose.x < 0.1 - 0.02
        assert [task["state"] for task in face.tasks.values()] == ["ERROR"]


@pytest.mark.parametrize("how", ["goto_pose", "goto_point", "goto"])
async def test_a_planner_abort_over_http_is_the_goal_error_of_each_call(how: str) -> None:
    async with robot_on_http(planner_abort="next") as (sim, robot, face):
        await navigating(robot)
        if how == "goto_pose":  # the task's verdict
            with pytest.raises(TaskFailed) as failed:
                await robot.goto_pose(1.5, 0.0, timeout=WAIT)
            assert failed.value.state == "ERROR"
        else:  # the goal rule: free and far from the target
            going = (
                robot.goto(0, timeout=WAIT)  # target 0 is (1.5, 0)
                if how == "goto"
                else robot.goto_point(1.5, 0.0, timeout=WAIT)
            )
            with pytest.raises(GoalAborted) as aborted:
                await going
            assert aborted.value.distance is not None
            assert aborted.value.distance > robot.arrive_tolerance
        assert sim.state.pose.x < 1.0
        assert [task["state"] for task in face.tasks.values()] == ["ERROR"]
