"""Failure policies (retry, skip, abort, goto a step) and the device's faults, on the simulator.

Faults: a refused goal, a planner abort, a frozen robot, a dropped link, charging that
starts mid-loop. Virtual clock: every second below is virtual.
"""

from __future__ import annotations

from typing import Any

import pytest

from galileo_async.missions import Mission, MissionReport
from galileo_async.protocol import Goto
from galileo_async.testing import play_mission, simulated_robot

pytestmark = pytest.mark.timeout(60)

#: A target id the simulator's map (6 targets) does not have: every goal to it is refused.
NO_SUCH_TARGET = 9


def mission(*steps: Any, **fields: Any) -> Mission:
    return Mission.model_validate({"mission": "test", **fields, "steps": list(steps)})


def endings(report: MissionReport) -> list[tuple[str, str]]:
    return [(step.path, step.ending) for step in report.steps]


async def test_retry_runs_the_step_again_after_a_planner_abort() -> None:
    plan = mission({"goto": 2, "on_failure": "retry 1"})
    async with simulated_robot() as (robot, device):
        device.abort_next_goal()
        report = (await play_mission(robot, plan)).report
        assert endings(report) == [("steps[0]", "reached")]
        assert report.steps[0].attempts == 2
        assert len(device.received(Goto)) == 2


async def test_retries_used_up_then_abort_fails_the_mission() -> None:
    plan = mission({"goto": NO_SUCH_TARGET, "on_failure": "retry 2"}, {"goto": 1})
    async with simulated_robot() as (robot, device):
        report = (await play_mission(robot, plan)).report
        assert report.ending == "failed"
        assert endings(report) == [("steps[0]", "rejected")]
        assert report.steps[0].attempts == 3
        assert report.error is not None
        assert report.error.startswith("steps[0]: ")
        assert device.received(Goto) == [Goto(NO_SUCH_TARGET)] * 3


async def test_a_refused_goal_once_then_reached() -> None:
    plan = mission({"goto": 1, "on_failure": {"retry": 1}})
    async with simulated_robot() as (robot, device):
        await robot.goto(2)  # a goal before: the refusal shows as -1 on a known id
        device.reject_next_goal()
        report = (await play_mission(robot, plan)).report
        assert endings(report) == [("steps[0]", "reached")]
        assert report.steps[0].attempts == 2


async def test_skip_goes_on_with_the_next_step() -> None:
    plan = mission({"goto": NO_SUCH_TARGET, "on_failure": "skip"}, {"goto": 1})
    async with simulated_robot() as (robot, _):
        report = (await play_mission(robot, plan)).report
    assert report.ending == "completed"
    assert endings(report) == [("steps[0]", "skipped"), ("steps[1]", "reached")]
    assert report.steps[0].error is not None


async def test_goto_a_named_step_continues_there() -> None:
    plan = mission(
        {"goto": NO_SUCH_TARGET, "on_failure": "goto dock"},
        {"goto": 1},
        {"goto": 0, "name": "dock"},
        {"dwell": 1},
    )
    async with simulated_robot() as (robot, _):
        report = (await play_mission(robot, plan)).report
    assert report.ending == "completed"
    assert endings(report) == [
        ("steps[0]", "rejected"), ("steps[2]", "reached"), ("steps[3]", "done"),
    ]  # fmt: skip


async def test_goto_into_a_loop_body_continues_that_loop_from_that_step() -> None:
    plan = mission(
        {"goto": NO_SUCH_TARGET, "on_failure": "goto inner"},
        {"loop": {"count": 2, "steps": [{"goto": 1}, {"goto": 2, "name": "inner"}]}},
    )
    async with simulated_robot() as (robot, _):
        report = (await play_mission(robot, plan)).report
    assert report.ending == "completed"
    assert endings(report) == [
        ("steps[0]", "rejected"),
        ("steps[1].loop.steps[1]", "reached"),
        ("steps[1].loop.steps[0]", "reached"),
        ("steps[1].loop.steps[1]", "reached"),
    ]
    loops = [step.loops["steps[1]"] for step in report.steps[1:]]
    assert loops == [1, 2, 2]
    assert report.loops_done == 2


async def test_a_step_timeout_is_the_goals_timeout() -> None:
    plan = mission({"goto": 2, "timeout": 1, "on_failure": "skip"}, {"dwell": 2, "timeout": 1})
    async with simulated_robot() as (robot, _):
        report = (await play_mission(robot, plan)).report
        status = robot.status
        assert status is not None
        assert not status.goal_active
    assert endings(report) == [("steps[0]", "skipped"), ("steps[1]", "timeout")]
    assert report.steps[0].duration == pytest.approx(1.0, abs=0.1)
    assert report.ending == "failed"


async def test_a_frozen_robot_stalls_the_goal_and_a_retry_after_the_thaw_arrives() -> None:
    plan = mission({"goto": 2, "on_failure": "retry 1"})
    async with simulated_robot(progress_timeout=5) as (robot, device):
        play = await play_mission(robot, plan, faults={1.0: device.freeze, 8.0: device.thaw})
        report = play.report
        assert endings(report) == [("steps[0]", "reached")]
        assert report.steps[0].attempts == 2
        assert "stalled" not in {step.ending for step in report.steps}
        started = [line for line in play.timeline() if "started (attempt 2)" in line]
        assert started


async def test_a_frozen_robot_without_retries_fails_stalled() -> None:
    plan = mission({"goto": 2})
    async with simulated_robot(progress_timeout=5) as (robot, device):
        report = (await play_mission(robot, plan, faults={1.0: device.freeze})).report
        device.thaw()
    assert endings(report) == [("steps[0]", "stalled")]
    assert report.ending == "failed"


async def test_charging_that_starts_mid_loop_pauses_the_mission_until_charged() -> None:
    plan = mission({"loop": {"count": 2, "steps": [{"goto": 1}, {"dwell": 2}, {"goto": 2}]}})
    async with simulated_robot(sim_options={"power": 27.5}) as (robot, device):
        play = await play_mission(robot, plan, faults={3.0: device.go_charge})
        report = play.report
        assert report.ending == "completed"
        assert [step.ending for step in report.steps] == ["reached", "done", "reached"] * 2
        first = report.steps[0]
        assert first.attempts == 2  # cut off by the robot's own charge, then run again
        assert first.duration > 10.0  # it waited for the charge (0.5 V at 0.05 V/s)
        assert not [s for s in report.steps if s.ending != "reached" and s.action == "goto"]


async def test_charging_that_starts_during_a_dwell_waits_before_the_next_goal() -> None:
    plan = mission({"dwell": 5}, {"goto": 1})
    async with simulated_robot(sim_options={"power": 27.8}) as (robot, device):
        play = await play_mission(robot, plan, faults={1.0: device.go_charge})
        report = play.report
        status = robot.status
        assert status is not None
    assert report.ending == "completed"
    goto = report.steps[1]
    assert goto.ending == "reached"
    assert goto.attempts == 1
    assert goto.duration > 4.0  # waited for the charge to finish before driving


@pytest.mark.parametrize("then", ["abort", "wait"])
async def test_a_dropped_link_that_stays_down_ends_the_mission_link_lost(then: str) -> None:
    plan = mission({"goto": 2}, on_link_loss={"then": then, "wait": 5})
    async with simulated_robot() as (robot, device):
        play = await play_mission(robot, plan, faults={1.0: device.drop_link})
        device.restore_link()
        report = play.report
    assert report.ending == "link lost"
    assert endings(report) == [("steps[0]", "link lost")]
    if then == "wait":
        assert "not back within 5 s" in (report.error or "")


async def test_a_dropped_link_back_within_the_wait_retries_the_step() -> None:
    plan = mission({"goto": 2}, on_link_loss={"then": "wait", "wait": 30})
    async with simulated_robot() as (robot, device):
        play = await play_mission(
            robot, plan, faults={1.0: device.drop_link, 4.0: device.restore_link}
        )
        report = play.report
    assert report.ending == "completed"
    assert endings(report) == [("steps[0]", "reached")]
    assert report.steps[0].attempts == 2
