"""Mission files: every step kind and shorthand loads, every problem is named with its line
and step, dump_mission round-trips, and the published JSON Schema is the model's."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import jsonschema
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from galileo_async.missions import (
    Mission,
    MissionFileError,
    dump_mission,
    load_mission,
    mission_schema,
    parse_mission,
)
from galileo_async.missions.model import (
    CallStep,
    ChargeStep,
    GotoPointStep,
    GotoPoseStep,
    GotoStep,
    LocalMoveStep,
    LoopStep,
    SayStep,
    SwitchMapStep,
    WaitStep,
    step_action,
)

DATA = Path(__file__).parent / "data"
ROOT = Path(__file__).parents[2]


def test_every_step_kind_and_shorthand_loads() -> None:
    mission = load_mission(DATA / "every_step.yaml")
    assert [step_action(step) for step in mission.steps] == [
        "goto", "dwell", "say", "wait", "call", "switch_map", "charge", "local_move",
        "goto_point", "goto_pose", "loop",
    ]  # fmt: skip
    goto, _, say, wait, call, switch, charge, move, point, pose, loop = mission.steps
    assert isinstance(goto, GotoStep)
    assert goto.goto == 3
    assert goto.name == "lobby"
    assert goto.on_failure.retry == 2
    assert goto.on_failure.then == "abort"
    assert goto.timeout == 120
    assert isinstance(say, SayStep)
    assert say.say == "hello"
    assert isinstance(wait, WaitStep)
    assert wait.wait.release == "operator"
    assert isinstance(call, CallStep)
    assert call.call.json_body == {"door": 1}
    assert call.call.expect_status == [200]
    assert call.call.expect_json == {"ok": True}
    assert isinstance(switch, SwitchMapStep)
    assert switch.switch_map.path == "route1"
    assert isinstance(charge, ChargeStep)
    assert charge.charge.until_percent == 90
    assert isinstance(move, LocalMoveStep)
    assert move.local_move.distance == -0.5
    assert isinstance(point, GotoPointStep)
    assert point.on_failure.goto == "dock"
    assert isinstance(pose, GotoPoseStep)
    assert pose.goto_pose.theta == 1.57
    assert isinstance(loop, LoopStep)
    assert loop.loop.count == 3
    assert loop.loop.steps[1].on_failure.then == "skip"
    assert loop.loop.steps[1].on_failure.retry == 1
    assert mission.on_link_loss.then == "wait"
    assert mission.on_link_loss.wait == 30


def test_bare_and_named_shorthands() -> None:
    text = """
mission: m
steps:
  - charge:
  - wait: {release: door, timeout: 5}
  - switch_map: floor2
  - loop: {count: forever, steps: [{dwell: 1, on_failure: skip}]}
"""
    charge, wait, switch, loop = parse_mission(text).steps
    assert isinstance(charge, ChargeStep)
    assert charge.charge.until_percent is None
    assert isinstance(wait, WaitStep)
    assert wait.wait.timeout == 5
    assert isinstance(switch, SwitchMapStep)
    assert switch.switch_map.map == "floor2"
    assert isinstance(loop, LoopStep)
    assert loop.loop.count is None


def test_every_problem_is_named_at_once_with_its_line_and_step() -> None:
    with pytest.raises(MissionFileError) as caught:
        load_mission(DATA / "broken.yaml")
    error = caught.value
    source = str(DATA / "broken.yaml")
    assert error.source == source
    assert error.line == 3
    assert error.step == "steps[0]"
    assert [problem.removeprefix(f"{source}:") for problem in error.problems] == [
        "3: steps[0]: goto: Input should be a valid integer, unable to parse string as an "
        "integer (got 'x')",
        "4: steps[0]: on_failure: 'retri 2' is none of abort, skip, retry N, goto STEP",
        "5: steps[1]: no action key: unknown key 'dwel' (did you mean 'dwell'?)",
        "6: steps[2] (name 'dock'): dwell: Input should be greater than or equal to 0 (got -1)",
        "7: steps[2] (name 'dock'): unknown key 'nam' (did you mean 'name'?)",
        "10: steps[3]: loop.count: Input should be greater than or equal to 1 (got 0)",
        "12: steps[3].loop.steps[0]: goto: Input should be less than or equal to 255 (got 300)",
        "13: steps[3].loop.steps[1] (name 'dock'): charge.until_percent: Input should be less "
        "than or equal to 100 (got 200)",
        "14: steps[3].loop.steps[1] (name 'dock'): name: 'dock' is the name of steps[2] too "
        "(names are unique)",
        "15: steps[3].loop.steps[1] (name 'dock'): on_failure: goes to 'dok', a step that does "
        "not exist (did you mean 'dock'?)",
        "16: steps[4]: one action per step: goto, say are several (make them separate steps)",
        "17: steps[5]: a step is a mapping with one action key (goto, goto_point, goto_pose, "
        "dwell, say, wait, call, switch_map, charge, local_move, loop), not 'oops'",
        "18: steps[6]: wait.release: missing (required)",
        "20: key 'goto' given twice (first on line 19)",
    ]
    assert str(error).startswith(f"{source}: 14 problems:\n")


def test_mission_level_problems_name_their_lines() -> None:
    with pytest.raises(MissionFileError) as caught:
        parse_mission("steps: []\nextra: 1\non_link_loss: {then: maybe}\n", source="m.yaml")
    assert caught.value.problems == [
        "m.yaml:1: mission: missing (required)",
        "m.yaml:1: steps: List should have at least 1 item after validation, not 0",
        "m.yaml:2: unknown key 'extra'",
        "m.yaml:3: on_link_loss.then: Input should be 'abort' or 'wait' (got 'maybe')",
    ]
    assert caught.value.step is None


@pytest.mark.parametrize(
    ("text", "line", "message"),
    [
        ("mission: [\n", 2, "YAML: while parsing a flow node expected the node content"),
        ("- goto: 1\n", 1, "no mission here: a mission file is a mapping"),
        ("", None, "no mission here"),
        ("mission: m\nsteps:\n  - goto: 1\n   name: x\n", 4, "YAML: "),
    ],
)
def test_what_is_not_a_mission_file(text: str, line: int | None, message: str) -> None:
    with pytest.raises(MissionFileError) as caught:
        parse_mission(text, source="f.yaml")
    assert caught.value.line == line
    assert message in caught.value.problems[0]


def test_a_jump_to_a_name_given_twice_is_reported_once_per_cause() -> None:
    text = (
        "mission: m\nsteps:\n  - {goto: 1, name: a, on_failure: goto b}\n  - {goto: 2, name: a}\n"
    )
    with pytest.raises(MissionFileError) as caught:
        parse_mission(text, source="f")
    assert caught.value.problems == [
        "f:3: steps[0] (name 'a'): on_failure: goes to 'b', a step that does not exist",
        "f:4: steps[1] (name 'a'): name: 'a' is the name of steps[0] too (names are unique)",
    ]


def test_dump_round_trips_the_example_and_uses_shorthands() -> None:
    mission = load_mission(DATA / "every_step.yaml")
    text = dump_mission(mission)
    assert parse_mission(text) == mission
    assert "  on_failure: retry 2\n" in text
    assert "- wait: operator\n" in text
    assert "  on_failure: goto dock\n" in text


_names = st.text("abcdefgh", min_size=1, max_size=6)
_numbers = st.floats(-50, 50, allow_nan=False).map(lambda v: round(v, 3))
_policies = st.sampled_from(["abort", "skip", "retry 1", "retry 3", {"retry": 2, "then": "skip"}])
_leaves = st.one_of(
    st.builds(lambda g, p: {"goto": g, "on_failure": p}, st.integers(0, 255), _policies),
    st.builds(lambda x, y: {"goto_point": {"x": x, "y": y}}, _numbers, _numbers),
    st.builds(lambda x, t: {"goto_pose": {"x": x, "y": 0, "theta": t}}, _numbers, _numbers),
    st.builds(lambda d: {"dwell": d, "timeout": d + 1}, st.floats(0, 100).map(abs)),
    st.builds(lambda r: {"wait": r}, _names),
    st.builds(lambda r, t: {"wait": {"release": r, "timeout": t}}, _names, st.integers(1, 99)),
    st.builds(lambda m: {"switch_map": {"map": m, "path": m + "p"}}, _names),
    st.sampled_from([{"charge": None}, {"charge": {"until_volts": 25.5}}, {"say": "hi: there"}]),
    st.builds(lambda d: {"local_move": {"distance": d / 10}}, st.integers(-99, 99)),
)
_steps = st.recursive(
    _leaves,
    lambda inner: st.builds(
        lambda count, steps: {"loop": {"count": count, "steps": steps}},
        st.one_of(st.none(), st.integers(1, 9), st.just("forever")),
        st.lists(inner, min_size=1, max_size=3),
    ),
    max_leaves=8,
)


@settings(max_examples=60, deadline=None)
@given(steps=st.lists(_steps, min_size=1, max_size=5), description=st.none() | _names)
def test_dump_round_trips_any_mission(steps: list[object], description: str | None) -> None:
    mission = Mission.model_validate({"mission": "m", "description": description, "steps": steps})
    assert parse_mission(dump_mission(mission)) == mission


def test_the_published_schema_is_the_models() -> None:
    published = json.loads((ROOT / "docs" / "mission.schema.json").read_text(encoding="utf-8"))
    assert published == mission_schema(), (
        "regenerate: galileo mission schema > docs/mission.schema.json"
    )


@pytest.mark.parametrize("name", ["every_step.yaml"])
def test_the_schema_accepts_the_files_that_load(name: str) -> None:
    data = yaml.safe_load((DATA / name).read_text(encoding="utf-8"))
    jsonschema.Draft202012Validator(mission_schema()).validate(data)


def test_the_schema_refuses_what_does_not_load() -> None:
    validator = jsonschema.Draft202012Validator(mission_schema())
    for steps in ([{"dwel": 3}], [{"goto": 1, "say": "x"}], [{"goto": 1, "on_failure": "retri"}]):
        assert not validator.is_valid({"mission": "m", "steps": steps}), steps


def test_importing_missions_needs_no_yaml() -> None:
    code = (
        "import sys; sys.modules['yaml'] = None\n"
        "import galileo_async.missions as m\n"
        "try:\n    m.parse_mission('mission: m')\n"
        "except ModuleNotFoundError as exc:\n    print(exc)\n"
    )
    result = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True
    )
    assert "pip install 'galileo-async[missions]'" in result.stdout
