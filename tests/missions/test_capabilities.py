"""What each step needs of the link (and check saying so), step paths, rejections, and the
call step's answer check (pure)."""

from __future__ import annotations

from typing import Any

import pytest

from galileo_async.missions import ACTION_KEYS, Mission, needs, unsupported
from galileo_async.missions.calls import holds
from galileo_async.missions.capabilities import HTTP_ONLY, REST_API
from galileo_async.missions.check import check_static
from galileo_async.missions.model import step_paths
from galileo_async.missions.offload import OffloadRejected
from galileo_async.missions.report import MissionRejected

EXAMPLES: dict[str, Any] = {
    "goto": 1, "goto_point": {"x": 1, "y": 2}, "goto_pose": {"x": 1, "y": 2}, "dwell": 1,
    "say": "hi", "wait": "operator", "call": {"url": "http://door.local/open"},
    "switch_map": "floor2", "charge": None, "local_move": {"distance": 1},
    "loop": {"count": 1, "steps": [{"dwell": 1}]},
}  # fmt: skip


def test_every_step_kind_has_an_example() -> None:
    assert set(EXAMPLES) == set(ACTION_KEYS)


@pytest.mark.parametrize("action", list(EXAMPLES))
def test_only_goto_pose_say_and_switch_map_need_the_http_api(action: str) -> None:
    plan = Mission.model_validate({"mission": "m", "steps": [{action: EXAMPLES[action]}]})
    step = plan.steps[0]
    assert needs(step) == (frozenset({REST_API}) if action in HTTP_ONLY else frozenset())
    assert bool(unsupported(plan, frozenset())) == (action in HTTP_ONLY)
    assert unsupported(plan, {REST_API}) == []


@pytest.mark.parametrize("action", list(EXAMPLES))
def test_check_names_the_steps_capabilities_names(action: str) -> None:
    plan = Mission.model_validate(
        {"mission": "m", "steps": [{"dwell": 1}, {"loop": {"count": 1, "steps": [
            {action: EXAMPLES[action], "name": "x"}]}}]}
    )  # fmt: skip
    notes = [(p.step, p.name, p.message) for p in check_static(plan) if "link" in p.message]
    assert notes == [(found.path, found.name, found.reason) for found in unsupported(plan, ())]


def test_an_offload_rejection_is_a_mission_rejection() -> None:
    rejected = OffloadRejected("m", ["steps[0]: say: the task chain has no speech action"])
    assert isinstance(rejected, MissionRejected)
    assert rejected.problems == ["steps[0]: say: the task chain has no speech action"]
    assert str(rejected) == (
        "mission 'm' cannot be offloaded: steps[0]: say: the task chain has no speech action"
    )


def test_step_paths_name_loops_steps() -> None:
    plan = Mission.model_validate(
        {
            "mission": "m",
            "steps": [
                {"goto": 1},
                {
                    "loop": {
                        "count": 2,
                        "steps": [
                            {"dwell": 1},
                            {"loop": {"count": 1, "steps": [{"say": "x", "name": "deep"}]}},
                        ],
                    }
                },
            ],
        }
    )
    paths = [path for path, _ in step_paths(plan.steps)]
    assert paths == [
        "steps[0]", "steps[1]", "steps[1].loop.steps[0]", "steps[1].loop.steps[1]",
        "steps[1].loop.steps[1].loop.steps[0]",
    ]  # fmt: skip
    (problem,) = unsupported(plan, ())
    assert str(problem) == (
        "steps[1].loop.steps[1].loop.steps[0] (deep): say needs an http:// or https:// link"
    )


@pytest.mark.parametrize(
    ("expected", "answer", "result"),
    [
        ({"ok": True}, {"ok": True, "more": 1}, True),
        ({"ok": True}, {"ok": False}, False),
        ({"ok": True}, None, False),
        ({"door": {"state": "open"}}, {"door": {"state": "open", "id": 1}}, True),
        ({"door": {"state": "open"}}, {"door": "open"}, False),
        ({"list": [1, 2]}, {"list": [1, 2]}, True),
        ({}, {"anything": 1}, True),
    ],
)
def test_an_answer_holds_the_expected_keys_and_values(
    expected: Any, answer: Any, result: bool
) -> None:
    assert holds(expected, answer) is result
