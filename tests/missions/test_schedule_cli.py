"""`galileo mission check|import` with schedules, and `galileo mission schedule`."""

from __future__ import annotations

import json
import signal
from pathlib import Path

import pytest

from galileo_async.cli import ExitCode
from galileo_async.missions.schedule_model import load_schedule, parse_schedule
from tests.cli.test_cli import invoke
from tests.cli.test_cli_served import _read_until as read_until
from tests.cli.test_cli_signals import finish, start

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


# --------------------------------------------------------------------------- mission schedule
SHORT = """\
schedule: short
time_zone: Europe/Berlin
windows:
  - days: every day
    start: "08:00"
    stop: "08:10"
    mission: patrol.yaml
    stop_pose: 3
"""
#: Open at any time of day: a run on the host's clock starts its mission at once.
ALL_DAY = """\
time_zone: UTC
windows:
  - {days: every day, start: "00:00", stop: "12:00", mission: patrol.yaml}
  - {days: every day, start: "12:00", stop: "00:00", mission: patrol.yaml}
"""


def test_schedule_sim_prints_the_timeline_of_a_window(tmp_path: Path) -> None:
    path = office(tmp_path, SHORT)
    result = invoke(
        "mission", "schedule", str(path), "--sim", "--days", "0.01", "--start",
        "2026-03-23T07:59", port=None,
    )  # fmt: skip
    assert result.exit_code == ExitCode.OK, result.output
    lines = result.stdout.splitlines()
    assert lines[0] == "2026-03-23 08:00:00 window 0 opened, closes at 08:10"
    assert lines[1].startswith("2026-03-23 08:10:")
    assert " mission 'patrol' cancelled: " in lines[1]  # the window closed mid-loop
    assert lines[-1].startswith("2026-03-23 08:10:")
    assert lines[-1].endswith("window 0 closed: window closed")


def test_schedule_sim_json_has_a_line_per_event(tmp_path: Path) -> None:
    path = office(tmp_path, SHORT)
    result = invoke(
        "--json", "mission", "schedule", str(path), "--sim", "--days", "0.01", "--start",
        "2026-03-23T07:59", port=None,
    )  # fmt: skip
    assert result.exit_code == ExitCode.OK, result.output
    events = [json.loads(line) for line in result.stdout.splitlines()]
    kinds = [event["event"] for event in events]
    assert kinds[0] == "window_opened"
    assert events[0]["at"] == "2026-03-23T08:00:00+01:00"
    assert events[0]["closes"] == "2026-03-23T08:10:00+01:00"
    assert {"step_started", "step_ended", "loop_started"} <= set(kinds)
    assert kinds[-2:] == ["mission_ended", "window_closed"]
    assert events[-1]["reason"] == "window closed"
    assert all("time" in event for event in events)


def test_schedule_of_a_broken_file_exits_2_with_its_line(tmp_path: Path) -> None:
    path = office(tmp_path, SHORT.replace('stop: "08:10"', 'stop: "08:70"'))
    result = invoke("mission", "schedule", str(path), "--sim", port=None)
    assert result.exit_code == ExitCode.USAGE
    assert f"error: {path}:6: windows[0]: stop: " in result.stderr
    as_json = invoke("--json", "mission", "schedule", str(path), port="sim://")
    assert as_json.exit_code == ExitCode.USAGE
    data = json.loads(as_json.stdout)
    assert (data["ok"], data["problems"][0]["line"]) == (False, 6)
    missing = invoke("mission", "schedule", str(tmp_path / "none.yaml"), port=None)
    assert missing.exit_code == ExitCode.USAGE
    assert "none.yaml" in missing.stderr


def test_schedule_options_that_do_not_fit_exit_2(tmp_path: Path) -> None:
    path = str(office(tmp_path, SHORT))
    bad = invoke("mission", "schedule", path, "--sim", "--start", "08:00", port=None)
    assert bad.exit_code == ExitCode.USAGE
    assert "YYYY-MM-DDTHH:MM" in bad.output
    real = invoke("mission", "schedule", path, "--start", "2026-03-23T08:00", port="sim://")
    assert real.exit_code == ExitCode.USAGE
    assert "--start is for --sim" in real.stderr


def test_schedule_with_a_mission_the_link_cannot_run_exits_2(tmp_path: Path) -> None:
    path = office(tmp_path, ALL_DAY, patrol="mission: patrol\nsteps: [{say: hello}]\n")
    result = invoke("mission", "schedule", str(path), port="sim://")
    assert result.exit_code == ExitCode.USAGE, result.output
    assert "mission 'patrol': " in result.stderr
    assert "say" in result.stderr


@pytest.mark.parametrize(("sig", "code"), [(signal.SIGTERM, 143), (signal.SIGINT, 130)])
def test_a_signal_ends_the_schedule_with_the_robot_stopped(
    tmp_path: Path, sig: signal.Signals, code: int
) -> None:
    path = office(tmp_path, ALL_DAY)
    process = start("--port", "sim://", "--json", "mission", "schedule", str(path))
    assert process.stdout is not None
    opened = read_until(process.stdout, '"step_started"')
    assert '"window_opened"' in opened
    returncode, out, err = finish(process, sig)
    assert returncode == code, err
    events = [json.loads(line) for line in out.splitlines() if line.startswith("{")]
    ended = [e for e in events if e.get("event") == "mission_ended"]
    assert ended[0]["report"]["ending"] == "cancelled"
    assert any(e.get("result") == "interrupted" and e.get("stop_sent") for e in events), out


def test_schedule_takes_the_vendors_timetask_with_its_points() -> None:
    timetask = str(DATA / "timeTask.json")
    result = invoke(
        "mission", "schedule", timetask, "--points", str(DATA / "maps"), "--sim",
        "--start", "2026-03-23T07:25", "--days", "0.03", port=None,
    )  # fmt: skip
    assert result.exit_code == ExitCode.OK, result.output
    lines = result.stdout.splitlines()
    assert lines[0] == "2026-03-23 07:30:00 window 0 opened, closes at 07:45"
    assert "mission 'mapSwithTasks[0] floor1/route1 07:30-07:45'" in lines[1]
    no_points = invoke("mission", "schedule", timetask, "--sim", port=None)
    assert no_points.exit_code == ExitCode.USAGE
    assert "needs --points" in no_points.stderr
