"""check_static and check_mission: the plan alone, then against a simulated robot on a
serial-like link (sim://) and on http:// (the simulator's HTTP face, virtual clock)."""

from __future__ import annotations

from typing import Any

import pytest

from galileo_async.battery import BATTERY_CURVE
from galileo_async.missions import Mission, Problem, check_mission, check_static
from galileo_async.missions.check import BUDGET, check_plan, has_errors
from galileo_async.missions.importers import ImportedPlan
from galileo_async.sim import SimConfig
from galileo_async.testing import simulated_robot
from tests.robot.goals.test_http_goals import http_robot

pytestmark = pytest.mark.timeout(60)


def mission(*steps: dict[str, Any]) -> Mission:
    return Mission.model_validate({"mission": "m", "steps": list(steps)})


def found(problems: list[Problem]) -> list[tuple[str, str | None, str]]:
    return [(p.severity, p.step, p.message) for p in problems]


def test_a_clean_mission_has_no_problems() -> None:
    plan = mission(
        {"goto": 1, "on_failure": "goto dock"}, {"dwell": 5}, {"charge": None, "name": "dock"}
    )
    assert check_static(plan) == []


def test_steps_after_a_forever_loop_are_unreachable_unless_a_jump_goes_there() -> None:
    plan = mission(
        {"loop": {"steps": [{"goto": 1, "on_failure": "goto dock"}, {"dwell": 1}]}},
        {"say": "bye"},
        {"charge": None, "name": "dock"},
        {"say": "docked"},
    )
    problems = [p for p in check_static(plan) if p.severity == "warning"]
    assert found(problems) == [
        ("warning", "steps[1]", "never reached: the loop steps[0] before it runs until stopped "
         "(a schedule's window closing ends it; give the loop a count otherwise)"),
    ]  # fmt: skip


def test_a_forever_loop_inside_a_loop_hides_the_rest_of_it() -> None:
    plan = mission(
        {"loop": {"count": 2, "steps": [{"loop": {"steps": [{"dwell": 1}]}}, {"goto": 1}]}}
    )
    assert [(p.step, p.severity) for p in check_static(plan)] == [
        ("steps[0].loop.steps[1]", "warning")
    ]


def test_a_jump_backwards_is_unbounded() -> None:
    plan = mission(
        {"goto": 1, "name": "a"},
        {"goto": 2, "on_failure": {"retry": 1, "then": "goto", "goto": "a"}},
    )
    (problem,) = check_static(plan)
    assert problem.severity == "warning"
    assert problem.step == "steps[1]"
    assert "on_failure goes back to 'a'" in problem.message
    assert (
        check_static(mission({"goto": 1, "name": "a", "on_failure": "goto a"}))[0].step
        == "steps[0]"
    )


@pytest.mark.parametrize(
    ("step", "severity", "text"),
    [
        ({"dwell": 10, "timeout": 5}, "error", "timeout 5 s ends the dwell of 10 s"),
        ({"dwell": 0}, "warning", "dwell 0 does nothing"),
        ({"dwell": 30000}, "warning", "is over 8 hours"),
        ({"wait": "door"}, "warning", "wait for 'door' has no timeout"),
        ({"wait": {"release": "d", "timeout": 60}, "timeout": 10}, "warning", "before the wait's"),
        ({"charge": {"until_volts": 48}}, "warning", "outside a 24 V pack's range"),
        ({"goto": 1, "timeout": 2}, "warning", "short for a goal"),
        (
            {"call": {"url": "http://d/x", "timeout": 20}, "timeout": 5},
            "warning",
            "the call's 20 s",
        ),
        ({"say": "hi"}, "note", "say needs an http:// or https:// link"),
        ({"switch_map": "f"}, "note", "switch_map needs an http:// or https:// link"),
        ({"goto_pose": {"x": 1, "y": 2}}, "note", "goto_pose needs an http:// or https:// link"),
    ],
)
def test_doubtful_steps(step: dict[str, Any], severity: str, text: str) -> None:
    problems = [p for p in check_static(mission(step)) if not p.message.startswith(RELEASE)]
    assert [(p.severity, p.step) for p in problems] == [(severity, "steps[0]")]
    assert text in problems[0].message
    assert has_errors(problems) == (severity == "error")
    assert str(problems[0]).startswith(f"{severity}: steps[0]: ")


def test_the_budget_is_the_simulators_motion_model() -> None:
    config = SimConfig()
    assert (BUDGET.speed, BUDGET.turn_rate, BUDGET.drain) == (
        config.max_speed, config.max_turn_rate, config.power_drain,
    )  # fmt: skip
    assert BUDGET.empty_volts == BATTERY_CURVE[0][0]


async def test_against_a_robot_on_a_serial_like_link() -> None:
    plan = mission(
        {"goto": 5}, {"goto": 6, "name": "far"}, {"goto_point": {"x": 1, "y": 1}},
        {"say": "hi"}, {"switch_map": "f"}, {"goto_pose": {"x": 1, "y": 2}}, {"goto": 9},
    )  # fmt: skip
    async with simulated_robot() as (robot, _):
        problems = await check_mission(plan, robot=robot)
    assert found(problems) == [
        ("error", "steps[1]", "target 6 is not in the robot's map: it has 6 targets (0-5)"),
        ("error", "steps[3]", "say needs an http:// or https:// link"),
        ("error", "steps[4]", "switch_map needs an http:// or https:// link"),
        ("error", "steps[5]", "goto_pose needs an http:// or https:// link"),
    ]  # after a switch_map the link cannot tell the new map's targets
    assert problems[0].name == "far"


async def test_a_loop_that_drains_the_battery_is_warned_of() -> None:
    loop = {
        "loop": {
            "count": 40,
            "steps": [
                {"goto_point": {"x": 20, "y": 0}},
                {"goto_point": {"x": 0, "y": 0}},
                {"dwell": 60},
            ],
        }
    }
    plan = mission(loop)
    async with simulated_robot(sim_options={"power": 23.0}) as (robot, _):
        (problem,) = await check_mission(plan, robot=robot)
        assert problem.severity == "warning"
        assert problem.step == "steps[0]"
        assert "for 40 passes" in problem.message
        assert "the robot has 1.00 V left" in problem.message
        short = mission({**loop, "loop": {**loop["loop"], "count": 1}})
        assert await check_mission(short, robot=robot) == []
    async with simulated_robot(sim_options={"power": 27.0}) as (robot, _):
        assert await check_mission(plan, robot=robot) == []


async def test_against_a_robot_on_http() -> None:
    plan = mission(
        {"goto": 1}, {"goto": 2, "name": "past"}, {"say": "hi"},
        {"switch_map": {"map": "floor9", "path": "x"}}, {"goto": 40},
        {"switch_map": {"map": "floor2", "path": "path2"}}, {"goto": 1}, {"goto": 2},
        {"goto_pose": {"x": 1, "y": 1}},
    )  # fmt: skip
    async with http_robot() as (_, robot, _face):
        problems = await check_mission(plan, robot=robot)
    assert found(problems) == [
        ("error", "steps[1]", "target 2 is not in the robot's map: it has 2 targets (0-1)"),
        ("error", "steps[3]", "map 'floor9' is not on the robot (it has: sim, floor2)"),
        ("error", "steps[7]", "target 2 is not in map 'floor2': it has 2 targets (0-1)"),
    ]


RELEASE = "a run needs the release "


def test_a_wait_notes_the_release_a_run_needs() -> None:
    plan = mission({"dwell": 1}, {"wait": {"release": "door", "timeout": 9}, "name": "w"})
    assert [str(p) for p in check_static(plan)] == [
        "note: steps[1] (name 'w'): a run needs the release 'door' (--release "
        "door=key|file:PATH|http:PORT|mqtt:URL, run_mission's releases); check cannot know it"
    ]


async def test_a_plans_missions_and_its_window_checks() -> None:
    first, second = (
        mission({"goto": 1}),
        Mission.model_validate({"mission": "n", "steps": [{"wait": "x"}]}),
    )
    plan = ImportedPlan([first, second])

    def no_windows(windows: Any) -> list[Problem]:
        return [Problem(None, None, f"{len(windows)} windows", "note")]

    result = await check_plan(plan, window_checks=[no_windows])
    assert [(name, p.severity) for name, p in result] == [
        ("n", "warning"), ("n", "note"), ("schedule", "note"),
    ]  # fmt: skip
