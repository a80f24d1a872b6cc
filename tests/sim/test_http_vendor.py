"""The simulator's HTTP tasks and status against the vendor's own code (docs/protocol.md §5).

Sources: BluewhaleRobot/system_monitor, branch noetic (e2502ff),
src/system_monitor/utils/galileo_status_service.py: how /galileo/status shows an HTTP nav task.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
from collections.abc import AsyncIterator, Callable
from typing import Any

import pytest

from galileo_async import GoalAborted
from galileo_async.http import HttpApi
from galileo_async.protocol import StartNavigation
from galileo_async.sim import SimConfig
from galileo_async.sim.device import SimDevice, Ticker
from galileo_async.sim.http import HttpFace
from tests.links.test_http_link import TARGETS, WAIT, http_of, navigating, robot_on_http

pytestmark = pytest.mark.timeout(60)

Step = Callable[[int], list[dict[str, Any]]]


@contextlib.asynccontextmanager
async def face_by_hand() -> AsyncIterator[tuple[HttpFace, HttpApi, Step]]:
    """An HTTP face whose frames the test steps (its clock never runs), navigating at frame 1.

    step(n): advance n frames; the n statuses the WebSocket would send, decoded.
    """
    config = SimConfig(targets=TARGETS, busy_on_start=0.0, visual_init_time=0.0)
    device = SimDevice(config, Ticker(), lambda: None)
    face = HttpFace(device)
    await face.start("127.0.0.1", 0, 0)
    sent: asyncio.Queue[str] = asyncio.Queue()
    face.sockets[None] = (None, sent)  # type: ignore[index]  # stands for one WebSocket
    device.listeners[face] = None

    def step(frames: int) -> list[dict[str, Any]]:
        device.advance(frames)
        return [json.loads(sent.get_nowait()) for _ in range(sent.qsize())]

    api = HttpApi(f"http://127.0.0.1:{face.address[1]}")
    device.execute([StartNavigation()])
    step(1)  # it looks at the current nav task at this frame, then at every 30th (once a second)
    try:
        yield face, api, step
    finally:
        face.sockets.clear()
        await api.close()
        await face.aclose()
        device.stop()


def goal_fields(statuses: list[dict[str, Any]]) -> list[tuple[int, int]]:
    return [(status["targetNumID"], status["targetStatus"]) for status in statuses]


# --- what /galileo/status shows of an HTTP nav task ----------------------------------------
# galileo_status_service.py L251-264: while GET /task?id=current_nav_action answers, its
# "index" (else -2), WORKING 1 / PAUSED 2 and current_distance replace the goal fields;
# L305-317: that answer is fetched at most once a second (688d24e, 2021-01-23).


@pytest.mark.parametrize("goal_id", [1, -2])
async def test_an_http_goal_shows_on_the_status_when_it_next_looks_at_the_task(
    goal_id: int,
) -> None:
    async with face_by_hand() as (face, api, step):
        before = step(9)[-1]  # frame 10
        assert (before["targetNumID"], before["navStatus"]) == (-1, 1)
        if goal_id == -2:  # a pose: "index" -1 or none, so -2
            await api.call("POST", "/navigation/start_nav_task", body={"x": 9, "y": 0, "theta": 0})
        else:
            task = await api.call("GET", "/navigation/move_to_index", {"index": goal_id})
            assert task["current_task"]["index"] == goal_id
        assert face.device.model.target_num_id == goal_id  # the robot drives at once
        shown = goal_fields(step(30))  # frames 11-40: the look at frame 31 sees the task
        assert shown[:20] == [(-1, before["targetStatus"])] * 20
        assert shown[20:] == [(goal_id, 1)] * 10


async def test_an_http_task_that_ended_shows_working_until_the_next_look() -> None:
    async with face_by_hand() as (_face, api, step):
        task = await api.call("GET", "/navigation/move_to_index", {"index": 0})  # 1.5 m
        statuses: list[dict[str, Any]] = []
        while (await api.call("GET", "/task", {"id": task["id"]}))["state"] != "COMPLETE":
            statuses += step(1)
            assert len(statuses) < 30 * 10
        ended = len(statuses)  # statuses[ended - 1] is the frame the task ended at
        assert ended % 30 != 0  # not on a look (statuses[30 k - 1] are the looks)
        statuses += step(30)
        shown = goal_fields(statuses)
        look = ended - ended % 30 + 29  # the next look
        assert shown[ended - 1 : look] == [(0, 1)] * (look - ended + 1)
        assert statuses[look - 1]["targetDistance"] > 0.0  # as it looked, a second before
        assert shown[look] == (0, 0)
        assert statuses[look]["targetDistance"] == 0.0


# --- a nav task the planner gave up on ---------------------------------------------------


async def test_a_pose_goal_given_up_a_few_centimetres_short_is_judged_by_the_goal_rule() -> None:
    # A 0.1 m goal aborted half way stops about 4 cm short: the task ends ERROR (no
    # arrival), but goto_pose follows the goal as every goal is followed: free within
    # arrive_tolerance of the pose is an arrival.
    async with robot_on_http(planner_abort="next") as (sim, robot, face):
        await navigating(robot)
        result = await http_of(robot).goto_pose(0.1, 0.0, timeout=WAIT)
        assert result.target_id == -2
        assert result.distance is not None
        assert 0.02 < result.distance < robot.arrive_tolerance
        assert sim.state.pose.x < 0.1 - 0.02
        assert [task["state"] for task in face.tasks.values()] == ["ERROR"]


@pytest.mark.parametrize("how", ["goto_pose", "goto_point", "goto"])
async def test_a_planner_abort_over_http_is_the_goal_error_of_each_call(how: str) -> None:
    async with robot_on_http(planner_abort="next") as (sim, robot, face):
        await navigating(robot)
        going = {  # target 0 is (1.5, 0); the goal rule: free and far from the target
            "goto": lambda: robot.goto(0, timeout=WAIT),
            "goto_point": lambda: robot.goto_point(1.5, 0.0, timeout=WAIT),
            "goto_pose": lambda: http_of(robot).goto_pose(1.5, 0.0, timeout=WAIT),
        }[how]
        with pytest.raises(GoalAborted) as aborted:
            await going()
        assert aborted.value.distance is not None
        assert aborted.value.distance > robot.arrive_tolerance
        assert sim.state.pose.x < 1.0
        assert [task["state"] for task in face.tasks.values()] == ["ERROR"]
