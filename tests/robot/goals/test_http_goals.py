"""robot.http.goto_pose is a goal like any other: the goal runner's checks, ends and events.

Against the simulator's HTTP face (REST and WebSocket on loopback, in this process), on the
virtual clock: every timeout below is virtual seconds.
"""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import AsyncIterator
from typing import Any

import pytest

import galileo_async as galileo
from galileo_async import (
    AcceptTimeout,
    GoalCancelled,
    GoalStalled,
    NotReady,
    OperationTimeout,
    TargetStatus,
)
from galileo_async import events as ev
from galileo_async.sim import Simulator
from galileo_async.sim.http import HttpFace
from galileo_async.testing import VirtualClock
from tests.links.test_http_link import http_of

pytestmark = pytest.mark.timeout(60)

#: Virtual seconds: a bound on every wait expected to succeed.
WAIT = 120.0
TARGETS = ((1.5, 0.0), (3.0, 0.0))
FAR = (30.0, 0.0)


@contextlib.asynccontextmanager
async def http_robot(
    robot_options: dict[str, Any] | None = None, **sim_options: Any
) -> AsyncIterator[tuple[Simulator, galileo.Robot, HttpFace]]:
    """A navigating Robot on http:// to the simulator's HTTP face, on the virtual clock."""
    clock = VirtualClock.install()
    try:
        async with Simulator(targets=TARGETS, **sim_options) as sim:
            face = await sim.serve_http()
            url = f"http://127.0.0.1:{face.address[1]}?ws_port={face.ws_address[1]}"
            options = {"map_targets": len(TARGETS), **(robot_options or {})}
            async with galileo.connect(url, **options) as robot:
                await robot.start_navigation(timeout=WAIT)
                yield sim, robot, face
    finally:
        clock.release()


def states(face: HttpFace) -> list[str]:
    return [task["state"] for task in face.tasks.values()]


async def goal_events(robot: galileo.Robot, until: type[ev.Event]) -> list[ev.GoalEvent]:
    """The goal events robot.events() reports, up to the first ``until``."""
    seen: list[ev.GoalEvent] = []
    async with asyncio.timeout(WAIT):
        async for event in robot.events():
            if isinstance(event, ev.GoalEvent):
                seen.append(event)
            if isinstance(event, until):
                return seen
    raise AssertionError("events() ended")


async def working(robot: galileo.Robot) -> None:
    await robot.wait_until(
        lambda s: s.target_num_id == -2 and s.target_status == TargetStatus.WORKING, timeout=WAIT
    )


async def test_inside_a_drive_block_it_is_not_ready_and_nothing_is_sent() -> None:
    async with http_robot() as (_, robot, face):
        async with robot.drive(0.1, 0.0):
            requests = face.requests
            with pytest.raises(NotReady, match="goto_pose: a drive session is active"):
                await http_of(robot).goto_pose(1.0, 0.0)
            # (the drive's own speeds go on meanwhile: no nav task among them)
            assert face.tasks == {}
            assert face.requests >= requests
        assert face.tasks == {}


async def test_a_newer_goal_preempts_it_with_goal_cancelled() -> None:
    async with http_robot() as (sim, robot, face):
        going = asyncio.ensure_future(http_of(robot).goto_pose(*FAR))
        await working(robot)
        result = await robot.goto(0, timeout=WAIT)
        with pytest.raises(GoalCancelled) as info:
            await going
        assert (info.value.target_id, info.value.preempted) == (-2, True)
        assert result.target_id == 0
        assert sim.state.pose.x == pytest.approx(1.5, abs=0.3)
        assert states(face) == ["CANCELLED", "COMPLETE"]


async def test_it_preempts_a_running_goto_the_same_way() -> None:
    async with http_robot() as (_, robot, face):
        going = asyncio.ensure_future(robot.goto(1, timeout=WAIT))
        await robot.wait_until(lambda s: s.target_num_id == 1 and s.goal_active, timeout=WAIT)
        result = await http_of(robot).goto_pose(0.5, 0.5, 1.0)
        with pytest.raises(GoalCancelled) as info:
            await going
        assert (info.value.target_id, info.value.preempted) == (1, True)
        assert result.target_id == -2
        assert states(face) == ["CANCELLED", "COMPLETE"]


async def test_cancel_ends_it_with_goal_cancelled_and_events_agree() -> None:
    async with http_robot() as (_, robot, face):
        events = asyncio.ensure_future(goal_events(robot, ev.GoalCancelledEvent))
        await asyncio.sleep(0)  # events() is listening before the goal starts
        going = asyncio.ensure_future(http_of(robot).goto_pose(*FAR))
        await working(robot)
        await robot.cancel(timeout=WAIT)
        with pytest.raises(GoalCancelled) as info:
            await going
        assert (info.value.target_id, info.value.preempted) == (-2, False)
        seen = await events
        assert [(e.name, e.target_id) for e in seen] == [
            ("GoalAccepted", -2),
            ("GoalCancelled", -2),
        ]
        assert states(face) == ["CANCELLED"]


async def test_stop_ends_it_at_once_with_goal_cancelled_by_stop() -> None:
    async with http_robot() as (sim, robot, face):
        going = asyncio.ensure_future(http_of(robot).goto_pose(*FAR))
        await working(robot)
        report = await robot.stop()
        with pytest.raises(GoalCancelled) as info:
            await going
        assert info.value.cancelled_by == "stop()"
        assert info.value.target_id == -2
        assert report.task is not None
        assert report.task in str(info.value)
        assert face.tasks[report.task]["state"] == "CANCELLED"
        assert not sim.state.status.goal_active


async def test_an_arrival_is_a_goal_result_and_events_say_the_same() -> None:
    async with http_robot() as (sim, robot, face):
        events = asyncio.ensure_future(goal_events(robot, ev.GoalReached))
        await asyncio.sleep(0)
        result = await http_of(robot).goto_pose(1.0, 1.0, 0.5)
        seen = await events
        assert [(e.name, e.target_id) for e in seen] == [("GoalAccepted", -2), ("GoalReached", -2)]
        assert result.target_id == -2
        assert result.distance is not None
        assert result.distance <= robot.arrive_tolerance
        assert sim.state.pose.y == pytest.approx(1.0, abs=0.3)
        assert states(face) == ["COMPLETE"]


async def test_no_progress_is_goal_stalled_and_the_task_is_stopped() -> None:
    async with http_robot({"progress_timeout": 5.0}, block_after=1.0) as (_, robot, face):
        events = asyncio.ensure_future(goal_events(robot, ev.GoalStalledEvent))
        await asyncio.sleep(0)
        with pytest.raises(GoalStalled) as info:
            await http_of(robot).goto_pose(*FAR)
        assert info.value.target_id == -2
        assert info.value.stalled_for == pytest.approx(5.0)
        stalled = (await events)[-1]
        assert isinstance(stalled, ev.GoalStalledEvent)
        assert stalled.target_id == -2
        await robot.wait_until(lambda s: not s.goal_active, timeout=WAIT)
        assert states(face) == ["CANCELLED"]


async def test_a_goal_the_status_never_shows_is_an_accept_timeout() -> None:
    async with http_robot() as (_, robot, face):
        face.task_refresh = 1e6  # from its next look on, the status never looks at a task
        frames = robot.link.frames
        await robot.wait_until(lambda s: robot.link.frames > frames + 31, timeout=WAIT)
        with pytest.raises(AcceptTimeout) as info:
            await http_of(robot).goto_pose(*FAR, accept_timeout=2.0)
        assert info.value.target_id == -2
        # Left while the robot may drive: its exit cancel stops the task.
        await robot.wait_until(lambda s: states(face) == ["CANCELLED"], timeout=WAIT)


async def test_the_goal_timeout_is_an_operation_timeout_and_stops_the_task() -> None:
    async with http_robot({"goal_timeout": 2.0}) as (_, robot, face):
        with pytest.raises(OperationTimeout, match=r"did not end within 2\.0 s"):
            await http_of(robot).goto_pose(*FAR)  # the Robot's goal_timeout, as goto
        await robot.wait_until(lambda s: not s.goal_active, timeout=WAIT)
        assert states(face) == ["CANCELLED"]
