"""`galileo mission schema|import|check`: output, --json and exit codes."""

from __future__ import annotations

import json
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
import yaml

from galileo_async.cli import ExitCode
from galileo_async.missions import load_mission, mission_schema, parse_mission
from galileo_async.sim import DEFAULT_TARGETS
from tests.cli.test_cli import invoke
from tests.cli.test_cli_served import HttpServedSim

DATA = Path(__file__).parent / "data"

pytestmark = pytest.mark.timeout(60)

#: CLI runs one after another against one served robot.
RUNS = 50


def test_schema_prints_the_json_schema() -> None:
    result = invoke("mission", "schema", port=None)
    assert result.exit_code == 0, result.output
    assert json.loads(result.stdout) == mission_schema()


def test_check_of_a_good_file_exits_0_and_names_warnings() -> None:
    result = invoke("mission", "check", str(DATA / "every_step.yaml"), port=None)
    assert result.exit_code == ExitCode.OK, result.output
    assert "warning: steps[3]: wait for 'operator' has no timeout" in result.stdout
    assert result.stdout.splitlines()[-1].endswith(": ok: 0 errors, 2 warnings")
    strict = invoke("mission", "check", "--strict", str(DATA / "every_step.yaml"), port=None)
    assert strict.exit_code == ExitCode.USAGE


def test_check_of_a_broken_file_names_every_problem_and_exits_2() -> None:
    result = invoke("mission", "check", str(DATA / "broken.yaml"), port=None)
    assert result.exit_code == ExitCode.USAGE
    lines = [line for line in result.stderr.splitlines() if line.startswith("error: ")]
    assert len(lines) == 14
    assert f"{DATA / 'broken.yaml'}:3: steps[0]: goto:" in lines[0]


def test_check_json() -> None:
    broken = invoke("--json", "mission", "check", str(DATA / "broken.yaml"), port=None)
    assert broken.exit_code == ExitCode.USAGE
    data = json.loads(broken.stdout)
    assert data["ok"] is False
    assert len(data["problems"]) == 14
    assert data["problems"][0] == {
        "severity": "error", "line": 3, "step": "steps[0]", "name": None,
        "message": "goto: Input should be a valid integer, unable to parse string as an "
        "integer (got 'x')",
    }  # fmt: skip
    good = invoke("mission", "check", "--json", str(DATA / "every_step.yaml"), port=None)
    data = json.loads(good.stdout)
    assert good.exit_code == 0
    assert data["ok"] is True
    assert "port" not in data
    assert {"mission": "lobby patrol", "severity": "note", "step": "steps[2]", "name": None,
            "message": "say needs an http:// or https:// link"} in data["problems"]  # fmt: skip


def test_check_against_the_simulator() -> None:
    result = invoke("--json", "mission", "check", str(DATA / "every_step.yaml"), port="sim://")
    assert result.exit_code == ExitCode.USAGE, result.output
    data = json.loads(result.stdout)
    assert data["port"] == "sim://"
    assert data["ok"] is False
    errors = [(p["step"], p["message"]) for p in data["problems"] if p["severity"] == "error"]
    assert errors == [
        ("steps[2]", "say needs an http:// or https:// link"),
        ("steps[5]", "switch_map needs an http:// or https:// link"),
        ("steps[9]", "goto_pose needs an http:// or https:// link"),
    ]


def test_check_of_an_imported_format(tmp_path: Path) -> None:
    result = invoke(
        "mission", "check", str(DATA / "timeTask.json"), "--points", str(DATA / "maps"), port=None
    )
    assert result.exit_code == 0, result.output
    assert "autoRunTasks[0] floor1/route1 08:00-12:00: warning: steps[2]" in result.stdout
    missing = invoke("mission", "check", str(DATA / "timeTask.json"), port=None)
    assert missing.exit_code == ExitCode.USAGE
    assert "needs the points of its paths" in missing.stderr
    absent = invoke("mission", "check", str(tmp_path / "none.yaml"), port=None)
    assert absent.exit_code == ExitCode.ERROR
    assert "cannot read" in absent.stderr


def test_import_prints_mission_files(tmp_path: Path) -> None:
    result = invoke(
        "mission", "import", str(DATA / "timeTask.json"), "--points", str(DATA / "maps"), port=None
    )
    assert result.exit_code == 0, result.output
    documents = result.stdout.split("---\n")
    assert len(documents) == 3
    assert documents[1].startswith("# window: days 1 (1 Monday … 7 Sunday), 08:00-12:00\n")
    missions = [parse_mission(document) for document in documents]
    assert [m.mission for m in missions][1] == "autoRunTasks[0] floor1/route1 08:00-12:00"
    nav2 = invoke("mission", "import", "--no-headings", "--loops", "1",
                  str(DATA / "nav2_panel_waypoints.yaml"), port=None)  # fmt: skip
    mission = parse_mission(nav2.stdout)
    assert yaml.safe_load(nav2.stdout)["steps"][0]["loop"]["count"] == 2
    assert "goto_point" in nav2.stdout
    assert mission.mission == "nav2_panel_waypoints"
    out = tmp_path / "patrol.yaml"
    out.write_text(nav2.stdout, encoding="utf-8")
    assert load_mission(out) == mission


def test_import_json() -> None:
    points = DATA / "maps" / "floor1" / "nav_route1.csv"
    timetask = str(DATA / "timeTask.json")
    result = invoke("mission", "import", "--json", timetask, "--points", str(points), port=None)
    assert result.exit_code == 0, result.output
    data = json.loads(result.stdout)
    assert [w["start"] for w in data["windows"]] == ["07:30", "08:00", "13:00"]
    assert data["windows"][1]["mission"] == data["missions"][1]
    assert data["notes"] == []


def test_import_rejects_a_format_it_does_not_know() -> None:
    result = invoke("mission", "import", "--format", "csv", str(DATA / "timeTask.json"), port=None)
    assert result.exit_code == ExitCode.USAGE
    assert "--format" in result.output


@pytest.fixture
def http_sim() -> Iterator[HttpServedSim]:
    sim = HttpServedSim(speed=5.0)
    try:
        yield sim
    finally:
        sim.close()


def test_import_with_the_points_of_an_http_robot(http_sim: HttpServedSim) -> None:
    result = invoke(
        "mission", "import", str(DATA / "timeTask.json"), "-p", http_sim.url,
        port=None,
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    loop = parse_mission(result.stdout.split("---\n")[1]).steps[1]
    assert len(loop.loop.steps) == 2 * len(DEFAULT_TARGETS)  # type: ignore[union-attr]


def test_check_against_an_http_robot(http_sim: HttpServedSim) -> None:
    check = invoke(
        "--json", "mission", "check", str(DATA / "every_step.yaml"), "-p", http_sim.url,
        port=None,
    )  # fmt: skip
    data = json.loads(check.stdout)
    assert data.get("port") == http_sim.url, check.output
    errors = [p["message"] for p in data["problems"] if p["severity"] == "error"]
    assert errors == ["map 'floor1' is not on the robot (it has: sim, floor2)"]
    assert check.exit_code == ExitCode.USAGE


@pytest.mark.timeout(180)
def test_checks_one_after_another_against_one_http_robot(http_sim: HttpServedSim) -> None:
    # Each run is a new event loop and a new session against the same face; the robot is
    # outside the command's loop, so invoke runs it on the real clock (a virtual one would
    # jump to the connect timeout while the face's thread answers).
    for run in range(RUNS):
        check = invoke(
            "--json", "mission", "check", str(DATA / "every_step.yaml"), "-p", http_sim.url,
            port=None,
        )  # fmt: skip
        assert check.exit_code == ExitCode.USAGE, f"run {run}: {check.output}"
        assert json.loads(check.stdout)["port"] == http_sim.url


def test_without_pyyaml_the_command_says_how_to_get_it(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "yaml", None)
    result = invoke("mission", "check", str(DATA / "every_step.yaml"), port=None)
    assert result.exit_code == ExitCode.ERROR
    assert "pip install 'galileo-async[cli,missions]'" in result.stderr
