"""`galileo mission check|import` with schedules, and `galileo mission schedule`."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from galileo_async.cli import ExitCode
from galileo_async.missions.schedule_model import load_schedule, parse_schedule
from tests.cli.test_cli import invoke

DATA = Path(__file__).parent / "data"

pytestmark = pytest.mark.timeout(120)

PATROL = "mission: patrol\nsteps:\n  - loop:\n      steps: [{goto: 1}, {dwell: 30}, {goto: 2}]\n"
OFFICE = """\
schedule: office
time_zone: Europe/Berlin
windows:
  - days: weekdays
    start: "08:00"
    stop: "12:00"
    mission: patrol.yaml
    stop_pose: 0
  - days: [mon]
    start: "11:00"
    stop: "13:00"
    mission: {mission: lunch, steps: [{dwell: 1e6}]}
"""


def office(folder: Path, text: str = OFFICE, patrol: str = PATROL) -> Path:
    (folder / "patrol.yaml").write_text(patrol, encoding="utf-8")
    path = folder / "office.yaml"
    path.write_text(text, encoding="utf-8")
    return path


def test_check_of_a_schedule_checks_its_windows_and_each_mission(tmp_path: Path) -> None:
    path = office(tmp_path)
    result = invoke("mission", "check", str(path), port=None)
    assert result.exit_code == ExitCode.OK, result.output
    lines = result.stdout.splitlines()
    assert f"{path}: schedule: warning: windows[1]: overlaps windows[0] on a day" in lines[-2]
    assert "lunch: warning: steps[0]" in result.stdout  # the mission's own check_static
    assert lines[-1] == f"{path}: ok: 0 errors, 2 warnings"
    strict = invoke("mission", "check", "--strict", "--json", str(path), port=None)
    assert strict.exit_code == ExitCode.USAGE
    data = json.loads(strict.stdout)
    assert {(p["mission"], p["step"]) for p in data["problems"]} == {
        ("schedule", "windows[1]"), ("lunch", "steps[0]"),
    }  # fmt: skip


def test_check_of_a_schedule_against_the_simulator(tmp_path: Path) -> None:
    path = office(tmp_path, patrol="mission: patrol\nsteps: [{goto: 200}]\n")
    result = invoke("--json", "mission", "check", str(path), port="sim://")
    assert result.exit_code == ExitCode.USAGE, result.output
    data = json.loads(result.stdout)
    errors = [(p["mission"], p["severity"]) for p in data["problems"]]
    assert ("patrol", "error") in errors
    assert ("schedule", "warning") in errors


def test_check_of_a_broken_schedule_names_each_line_and_exits_2(tmp_path: Path) -> None:
    text = OFFICE.replace('stop: "12:00"', 'stop: "12:75"').replace("{dwell: 1e6}", "{dwel: 1}")
    path = office(tmp_path, text, patrol="mission: patrol\nsteps: [{goto: x}]\n")
    result = invoke("mission", "check", str(path), port=None)
    assert result.exit_code == ExitCode.USAGE
    errors = [line for line in result.stderr.splitlines() if line.startswith("error: ")]
    assert errors[0].startswith(f"error: {path}:6: windows[0]: stop: ")
    assert errors[1].startswith(f"error: {path}:7: windows[0]: mission patrol.yaml: ")
    assert errors[2].startswith(f"error: {path}:12: windows[1].mission.steps[0]: no action key")
    assert len(errors) == 3


def test_import_of_a_timetask_as_one_schedule(tmp_path: Path) -> None:
    timetask = str(DATA / "timeTask.json")
    result = invoke(
        "mission", "import", "--schedule", timetask, "--points", str(DATA / "maps"), port=None
    )
    assert result.exit_code == ExitCode.OK, result.output
    schedule = parse_schedule(result.stdout, source="timeTask.yaml")
    assert schedule.schedule == "timeTask"
    assert [(w.start.hour, w.stop.hour) for w in schedule.windows] == [(7, 7), (8, 12), (13, 18)]
    assert schedule.windows[1].days == (0,)
    assert [w.stop_pose for w in schedule.windows] == [None, "dock", 1]
    missions = [w.mission for w in schedule.windows]
    assert [getattr(m, "mission", None) for m in missions][1] == (
        "autoRunTasks[0] floor1/route1 08:00-12:00"
    )
    # The same missions as the per-window import prints.
    plain = invoke("mission", "import", "--json", timetask, "--points", str(DATA / "maps"),
                   port=None)  # fmt: skip
    assert [
        m.model_dump(mode="json", by_alias=True, exclude_defaults=True)  # type: ignore[union-attr]
        for m in missions
    ] == json.loads(plain.stdout)["missions"]
    saved = tmp_path / "timeTask.yaml"
    saved.write_text(result.stdout, encoding="utf-8")
    assert load_schedule(saved) == schedule
    as_json = invoke("mission", "import", "--schedule", "--json", timetask,
                     "--points", str(DATA / "maps"), port=None)  # fmt: skip
    assert json.loads(as_json.stdout)["schedule"]["schedule"] == "timeTask"


def test_import_schedule_of_a_plan_without_windows_fails() -> None:
    nav2 = str(DATA / "nav2_panel_waypoints.yaml")
    result = invoke("mission", "import", "--schedule", nav2, port=None)
    assert result.exit_code == ExitCode.ERROR
    assert "has no time windows" in result.stderr
