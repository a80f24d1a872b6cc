"""run_mission on the simulator (virtual clock): every step kind, loops, the report, events."""

from __future__ import annotations

import math
from typing import Any

import anyio
import pytest

from galileo_async import ChargeStatus
from galileo_async.battery import battery_charge
from galileo_async.missions import (
    LoopStarted,
    Mission,
    MissionEnded,
    MissionEvent,
    MissionRejected,
    StepEnded,
    StepStarted,
    mission_events,
    run_mission,
)
from galileo_async.protocol import StartCharging
from galileo_async.testing import play_mission, simulated_robot

pytestmark = pytest.mark.timeout(60)


def mission(*steps: Any, **fields: Any) -> Mission:
    """A Mission named "test" of ``steps`` (mappings as in a mission file)."""
    return Mission.model_validate({"mission": "test", **fields, "steps": list(steps)})


async def test_goto_dwell_and_a_counted_loop_complete_in_order() -> None:
    plan = mission(
        {"goto": 1, "name": "first"},
        {"dwell": 5},
        {"loop": {"count": 2, "steps": [{"goto": 2}, {"goto": 0}]}},
    )
    async with simulated_robot() as (robot, device):
        play = await play_mission(robot, plan)
        report = play.report
        assert report.ending == "completed"
        assert report.completed
        assert [s.path for s in report.steps] == [
            "steps[0]", "steps[1]",
            "steps[2].loop.steps[0]", "steps[2].loop.steps[1]",
            "steps[2].loop.steps[0]", "steps[2].loop.steps[1]",
        ]  # fmt: skip
        assert [s.ending for s in report.steps] == ["reached", "done"] + ["reached"] * 4
        assert report.steps[0].name == "first"
        assert report.loops_done == 2
        assert [s.loops for s in report.steps[2:]] == [{"steps[2]": 1}] * 2 + [{"steps[2]": 2}] * 2
        dwell = report.steps[1]
        assert dwell.duration == pytest.approx(5.0, abs=0.05)
        assert dwell.distance_m == 0.0
        assert report.steps[0].distance_m > 1.0
        assert report.distance_m == pytest.approx(sum(s.distance_m for s in report.steps))
        status = robot.status
        assert status is not None
        assert status.target_num_id == 0
        assert math.dist((device.pose.x, device.pose.y), device.state.targets[0]) < 0.3


async def test_progress_events_come_in_order_and_end_with_the_report() -> None:
    plan = mission({"loop": {"count": 2, "steps": [{"dwell": 1}]}}, {"goto": 1})
    seen: list[MissionEvent] = []
    async with simulated_robot() as (robot, _):
        report = await run_mission(robot, plan, on_progress=seen.append)
    kinds = [event.kind for event in seen]
    assert kinds == [
        "loop_started", "step_started", "step_ended",
        "loop_started", "step_started", "step_ended",
        "step_started", "step_ended", "mission_ended",
    ]  # fmt: skip
    assert isinstance(seen[0], LoopStarted)
    assert (seen[0].iteration, seen[0].count) == (1, 2)
    assert isinstance(seen[1], StepStarted)
    assert seen[1].attempt == 1
    assert isinstance(seen[2], StepEnded)
    assert seen[2].step == report.steps[0]
    assert isinstance(seen[-1], MissionEnded)
    assert seen[-1].report == report
    assert [event.at for event in seen] == sorted(event.at for event in seen)
    line = seen[-1].to_json()
    assert line["event"] == "mission_ended"
    assert line["report"]["ending"] == "completed"
    assert seen[2].to_json()["step"]["ending"] == "done"


async def test_goto_point() -> None:
    plan = mission({"goto_point": {"x": 1.0, "y": 1.0}})
    async with simulated_robot() as (robot, device):
        report = await run_mission(robot, plan)
        assert [s.ending for s in report.steps] == ["reached"]
        assert math.dist((device.pose.x, device.pose.y), (1.0, 1.0)) < 0.3


async def test_local_move_turns_by_the_angle_then_drives_the_distance() -> None:
    plan = mission({"local_move": {"angle": math.pi / 2, "distance": 0.5}})
    async with simulated_robot() as (robot, device):
        device.place(0.0, 0.0, 0.0)
        report = await run_mission(robot, plan)
        assert [s.ending for s in report.steps] == ["done"]
        assert math.dist((device.pose.x, device.pose.y), (0.0, 0.5)) < 0.08
        assert device.pose.theta == pytest.approx(math.pi / 2, abs=0.1)
        assert report.steps[0].distance_m == pytest.approx(0.5, abs=0.08)
        status = await robot.wait_until(lambda s: s.current_speed_x == 0.0, 5)
        assert status.current_speed_theta == 0.0


async def test_local_move_backwards() -> None:
    plan = mission({"local_move": {"distance": -0.4}})
    async with simulated_robot() as (robot, device):
        device.place(0.0, 0.0, 0.0)
        report = await run_mission(robot, plan)
        assert report.ending == "completed"
        assert device.pose.x == pytest.approx(-0.4, abs=0.06)


@pytest.mark.parametrize(
    ("until", "check"),
    [
        ({"until_percent": 60}, lambda power: battery_charge(power) >= 60),
        ({"until_volts": 25.6}, lambda power: power >= 25.6),
        (None, lambda power: True),
    ],
)
async def test_charge_docks_and_waits_for_the_level(until: Any, check: Any) -> None:
    plan = mission({"charge": until}, {"goto": 1})
    seen: list[tuple[str, float, int]] = []
    async with simulated_robot(sim_options={"power": 25.0}) as (robot, device):

        def charged(event: MissionEvent) -> None:
            status = robot.status
            if isinstance(event, StepEnded) and status is not None:
                seen.append((event.step.action, status.power, status.charge_status))

        report = await run_mission(robot, plan, on_progress=charged)
        assert report.ending == "completed"
        assert device.received(StartCharging)
    (action, power, charge_status), _ = seen
    assert action == "charge"
    assert charge_status in (ChargeStatus.CHARGING, ChargeStatus.CHARGED)
    assert check(power)
    assert report.steps[0].distance_m > 0.5  # it drove to the dock (-1, 0)


async def test_wait_for_a_release_and_its_timeout() -> None:
    released = False

    async def operator() -> None:
        nonlocal released
        released = True

    plan = mission({"wait": "operator"}, {"wait": {"release": "never", "timeout": 3}})

    async def never() -> None:
        await anyio.sleep_forever()

    async with simulated_robot() as (robot, _):
        report = await run_mission(robot, plan, releases={"operator": operator, "never": never})
    assert released
    assert [s.ending for s in report.steps] == ["done", "timeout"]
    assert report.ending == "failed"
    assert report.steps[1].duration == pytest.approx(3.0, abs=0.05)


async def test_a_missing_release_and_http_steps_are_rejected_before_anything_moves() -> None:
    plan = mission(
        {"goto": 1},
        {"loop": {"count": 1, "steps": [{"say": "hello", "name": "greet"}]}},
        {"wait": "door"},
        {"goto_pose": {"x": 1, "y": 0}},
    )
    async with simulated_robot() as (robot, device):
        device.clear()
        with pytest.raises(MissionRejected) as info:
            await run_mission(robot, plan)
        assert device.commands == []
    problems = info.value.problems
    assert problems == [
        "steps[1].loop.steps[0] (greet): say needs an http:// or https:// link",
        "steps[3]: goto_pose needs an http:// or https:// link",
        "steps[2]: no release 'door' was given",
    ]
    assert isinstance(info.value, ValueError)


async def test_a_release_that_raises_fails_its_step() -> None:
    async def broken() -> None:
        raise RuntimeError("the button is gone")

    plan = mission({"wait": "operator", "on_failure": "skip"}, {"dwell": 1})
    async with simulated_robot() as (robot, _):
        report = await run_mission(robot, plan, releases={"operator": broken})
    assert [s.ending for s in report.steps] == ["skipped", "done"]
    assert report.steps[0].error == "release 'operator': RuntimeError: the button is gone"


async def test_an_on_progress_that_raises_is_logged_and_the_run_goes_on(
    caplog: pytest.LogCaptureFixture,
) -> None:
    def broken(event: MissionEvent) -> None:
        raise RuntimeError(event.kind)

    async with simulated_robot() as (robot, _):
        report = await run_mission(robot, mission({"dwell": 1}), on_progress=broken)
    assert report.ending == "completed"
    assert "on_progress failed" in caplog.text


async def test_mission_events_iterates_until_the_mission_ended() -> None:
    plan = mission({"goto": 1}, {"dwell": 3})
    stream = mission_events()
    kinds: list[str] = []
    async with simulated_robot() as (robot, _), anyio.create_task_group() as group:
        group.start_soon(lambda: run_mission(robot, plan, on_progress=stream))
        async for event in stream:
            kinds.append(event.kind)
    assert kinds == ["step_started", "step_ended", "step_started", "step_ended", "mission_ended"]
    assert stream.dropped == 0


async def test_a_slow_reader_of_mission_events_loses_the_oldest() -> None:
    stream = mission_events(maxlen=2)
    async with simulated_robot() as (robot, _):
        await run_mission(robot, mission({"dwell": 1}, {"dwell": 1}), on_progress=stream)
    kinds = [event.kind async for event in stream]
    assert kinds == ["step_ended", "mission_ended"]
    assert stream.dropped == 3
