"""The user's stop is the last word: stop()/cancel() mid-step and the five cancellation ways
end the mission at once, nothing retried, the robot stopped and no task left running."""

from __future__ import annotations

import asyncio
from collections.abc import Awaitable, Callable
from typing import Any

import anyio
import pytest

from galileo_async import Robot
from galileo_async.missions import Mission, MissionEnded, MissionEvent, MissionReport, run_mission
from galileo_async.protocol import Goto, StartCharging
from galileo_async.robot.stopping import in_motion
from galileo_async.testing import play_mission, simulated_robot
from tests.support.cancel_ways import WAYS, stop_waiting

pytestmark = pytest.mark.timeout(60)


def mission(*steps: Any, **fields: Any) -> Mission:
    return Mission.model_validate({"mission": "test", **fields, "steps": list(steps)})


def assert_stopped(robot: Robot) -> None:
    """The status shows no goal, no patrol, no docking and no speed."""
    status = robot.status
    assert status is not None
    assert in_motion(status) == ()


async def forever() -> None:
    await anyio.sleep_forever()


#: Each step kind a stop can come in, with the mission around it (every step retried).
MID = {
    "goal": {"goto": 2, "on_failure": "retry 3"},
    "dwell": {"dwell": 600, "on_failure": "retry 3"},
    "wait": {"wait": "operator", "on_failure": "retry 3"},
    "charge": {"charge": {"until_percent": 100}, "on_failure": "retry 3"},
    "local_move": {"local_move": {"distance": 5}, "on_failure": "retry 3"},
}


async def run_and_stop(
    robot: Robot, plan: Mission, stop: Callable[[], Awaitable[object]], after: float
) -> tuple[MissionReport, list[MissionEvent]]:
    seen: list[MissionEvent] = []
    running = asyncio.ensure_future(
        run_mission(robot, plan, releases={"operator": forever}, on_progress=seen.append)
    )
    await asyncio.sleep(after)
    assert not running.done()
    await stop()
    return await running, seen


@pytest.mark.parametrize("kind", list(MID))
async def test_stop_mid_step_ends_the_mission_stopped_and_retries_nothing(kind: str) -> None:
    plan = mission(MID[kind], {"goto": 1, "name": "after"})
    async with simulated_robot() as (robot, device):
        report, _ = await run_and_stop(robot, plan, robot.stop, after=3.0)
        device.clear()
        await asyncio.sleep(5)  # nothing more is sent: no retry, no next step
        assert device.received(Goto, StartCharging) == []
        assert_stopped(robot)
    assert report.ending == "stopped"
    assert report.stopped_by == "stop()"
    assert len(report.steps) == 1
    step = report.steps[0]
    assert (step.ending, step.attempts) == ("stopped", 1)
    assert step.error == "stopped by stop()"


async def test_cancel_mid_goal_ends_the_mission_stopped_by_cancel() -> None:
    plan = mission({"goto": 2, "on_failure": "retry 3"}, {"goto": 1})
    async with simulated_robot() as (robot, device):
        report, _ = await run_and_stop(robot, plan, robot.cancel, after=2.0)
        assert_stopped(robot)
        assert device.received(Goto) == [Goto(2)]
    assert report.ending == "stopped"
    assert report.stopped_by == "cancel()"


async def test_a_forever_loop_ends_on_stop() -> None:
    plan = mission({"loop": {"count": "forever", "steps": [{"goto": 1}, {"goto": 2}]}})
    async with simulated_robot() as (robot, _):
        report, seen = await run_and_stop(robot, plan, robot.stop, after=40.0)
        assert_stopped(robot)
    assert report.ending == "stopped"
    assert report.loops_done >= 1
    assert isinstance(seen[-1], MissionEnded)


async def test_pause_does_not_end_the_mission_and_resume_goes_on() -> None:
    plan = mission({"goto": 2})
    async with simulated_robot() as (robot, _):
        running = asyncio.ensure_future(run_mission(robot, plan))
        await asyncio.sleep(2)
        await robot.pause()
        await asyncio.sleep(5)
        assert not running.done()
        await robot.resume()
        report = await running
    assert report.ending == "completed"


@pytest.mark.parametrize("how", WAYS)
@pytest.mark.parametrize("kind", ["goal", "dwell", "charge"])
async def test_every_cancellation_way_leaves_the_robot_stopped(how: str, kind: str) -> None:
    plan = mission(MID[kind], {"goto": 1})
    seen: list[MissionEvent] = []
    async with simulated_robot() as (robot, device):

        async def run() -> None:
            await run_mission(robot, plan, on_progress=seen.append)

        await stop_waiting(how, run, 3.0)
        assert_stopped(robot)
        device.clear()
        await asyncio.sleep(5)
        assert device.received(Goto, StartCharging) == []
    ended = seen[-1]
    assert isinstance(ended, MissionEnded)
    assert ended.report.ending == "cancelled"
    assert ended.report.steps[-1].ending == "cancelled"


async def test_a_stop_as_the_charging_pause_ends_sends_no_goal(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The stop lands as the wait ends, with no checkpoint left to deliver its cancellation."""
    from galileo_async.missions import runner as runner_module

    until_charged = runner_module._Run._until_charged

    async def charged_then_stopped(run: Any) -> None:
        await until_charged(run)
        run._user_stop("stop()")  # what robot.stop()'s listener does, at the last moment

    monkeypatch.setattr(runner_module._Run, "_until_charged", charged_then_stopped)
    plan = mission({"dwell": 5}, {"goto": 1})
    async with simulated_robot(sim_options={"power": 27.8}) as (robot, device):
        report = (await play_mission(robot, plan, faults={1.0: device.go_charge})).report
        assert device.received(Goto) == []
    assert report.ending == "stopped"
    assert report.stopped_by == "stop()"
