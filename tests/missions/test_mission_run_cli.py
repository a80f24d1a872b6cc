"""``galileo mission run`` and ``galileo fleet mission run``: exit codes, lines, JSON lines."""

from __future__ import annotations

import json
import signal
from pathlib import Path
from typing import Any

import pytest

from galileo_async.cli import ExitCode
from galileo_async.cli.mission_run import mission_exit_code
from galileo_async.missions import MissionReport
from tests.cli.test_cli import invoke
from tests.cli.test_cli_served import HttpServedSim
from tests.cli.test_cli_served import _read_until as read_until
from tests.cli.test_cli_signals import finish, start
from tests.missions.test_mission_cli import http_sim  # noqa: F401  (a fixture)

pytestmark = pytest.mark.timeout(120)

LOBBY: dict[str, Any] = {
    "mission": "lobby",
    "steps": [
        {"goto": 1, "name": "lobby"},
        {"dwell": 30},
        {"loop": {"count": 2, "steps": [{"goto": 2}, {"wait": "operator"}]}},
    ],
}


def write(folder: Path, plan: dict[str, Any], name: str = "mission.json") -> str:
    path = folder / name
    path.write_text(json.dumps(plan), encoding="utf-8")
    return str(path)


def lines(output: str) -> list[dict[str, Any]]:
    return [json.loads(line) for line in output.splitlines() if line.startswith("{")]


def test_run_prints_a_line_per_step_and_exits_0(tmp_path: Path) -> None:
    plan = write(tmp_path, {"mission": "short", "steps": [{"goto": 1, "name": "a"}, {"dwell": 2}]})
    result = invoke("mission", "run", plan, port=None)
    assert result.exit_code == 0, result.output
    out = result.stdout.splitlines()
    assert out[0].startswith("steps[0] (a) goto reached in ")
    assert out[1].startswith("steps[1] dwell done in 2.0 s")
    assert out[-1].startswith("mission 'short' completed: 2 steps, 0 loops")


def test_run_json_prints_a_line_per_event(tmp_path: Path) -> None:
    plan = write(
        tmp_path, {"mission": "short", "steps": [{"loop": {"count": 1, "steps": [{"dwell": 1}]}}]}
    )
    result = invoke("--json", "mission", "run", plan, port=None)
    assert result.exit_code == 0, result.output
    events = lines(result.stdout)
    assert [e["event"] for e in events] == [
        "loop_started", "step_started", "step_ended", "mission_ended",
    ]  # fmt: skip
    assert all("time" in e and e["mission"] == "short" for e in events)
    assert events[2]["step"]["ending"] == "done"
    assert events[-1]["report"]["ending"] == "completed"


@pytest.mark.parametrize(
    ("step", "code"),
    [
        ({"goto": 9}, ExitCode.REJECTED),
        ({"goto": 9, "on_failure": "skip"}, ExitCode.OK),
        ({"goto": 2, "timeout": 1}, ExitCode.TIMEOUT),
        ({"call": {"url": "http://127.0.0.1:1/x", "timeout": 1}}, ExitCode.ERROR),
    ],
    ids=["rejected", "skipped", "timeout", "failed"],
)
def test_the_exit_code_tells_how_the_mission_ended(
    tmp_path: Path, step: dict[str, Any], code: ExitCode
) -> None:
    plan = write(tmp_path, {"mission": "m", "steps": [step]})
    result = invoke("mission", "run", plan, port=None)
    assert result.exit_code == code, result.output


def test_a_mission_the_link_cannot_run_exits_2_naming_every_problem(tmp_path: Path) -> None:
    plan = write(tmp_path, {"mission": "m", "steps": [{"say": "hi"}, {"wait": "door"}]})
    result = invoke("--json", "mission", "run", plan, port=None)
    assert result.exit_code == ExitCode.USAGE, result.output
    problems = [line["message"] for line in lines(result.stdout)]
    assert problems == [
        "mission 'm': steps[0]: say needs an http:// or https:// link",
        "mission 'm': steps[1]: no release 'door' was given",
    ]


@pytest.mark.parametrize(
    ("text", "args", "message"),
    [
        ("{", (), "bad.json:1: YAML: "),
        ('{"mission": "m", "steps": []}', (), "steps"),
        (json.dumps(LOBBY), ("--release", "operator"), "give NAME=key"),
        (
            json.dumps(LOBBY),
            ("--release", "operator=mouse"),
            "give NAME=key, NAME=file:PATH, NAME=http:[HOST:]PORT",
        ),
    ],
    ids=["not a mission", "no steps", "release without how", "unknown release"],
)
def test_usage_errors_exit_2(
    tmp_path: Path, text: str, args: tuple[str, ...], message: str
) -> None:
    path = tmp_path / "bad.json"
    path.write_text(text, encoding="utf-8")
    result = invoke("mission", "run", str(path), *args, port=None)
    assert result.exit_code == ExitCode.USAGE, result.output
    assert message in result.output


def test_a_bad_file_names_the_file_the_line_and_the_step(tmp_path: Path) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text("mission: m\nsteps:\n  - goto: 1\n  - dwell: -3\n", encoding="utf-8")
    result = invoke("mission", "run", str(path), port=None)
    assert result.exit_code == ExitCode.USAGE, result.output
    assert f"{path}:4: steps[1]: dwell: " in result.output


TIMETASK = {
    "autoRunTasks": [
        {"whichDay": 0, "startTime": "08:00", "stopTime": "09:00", "mapName": "sim",
         "pathName": "path1", "waitTime": 1, "stopPose": 0, "loopCount": 1},
        {"whichDay": 0, "startTime": "13:00", "stopTime": "18:00", "mapName": "floor2",
         "pathName": "path2", "waitTime": 0, "stopPose": 1, "loopCount": 2},
    ]
}  # fmt: skip


def test_a_timetask_file_runs_the_task_named_with_task(tmp_path: Path) -> None:
    plan = write(tmp_path, TIMETASK, "timeTask.json")
    points = tmp_path / "nav.csv"
    points.write_text("1 0 0\n2 0 0\n", encoding="utf-8")
    several = invoke("mission", "run", plan, "--points", str(points), "--sim", port=None)
    assert several.exit_code == ExitCode.USAGE, several.output
    assert "has 2 tasks: name the one to run with --task" in several.output
    assert "'autoRunTasks[1] floor2/path2 13:00-18:00'" in several.output
    unknown = invoke("mission", "run", plan, "--points", str(points), "--task", "x", port=None)
    assert unknown.exit_code == ExitCode.USAGE, unknown.output
    assert "has no task 'x'" in unknown.output
    result = invoke(
        "--json", "mission", "run", plan, "--points", str(points), "--task", "autoRunTasks[0]",
        "--sim", port=None,
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    events = lines(result.stdout)
    assert {e["mission"] for e in events} == {"autoRunTasks[0] sim/path1 08:00-09:00"}
    ended = [e["step"]["action"] for e in events if e["event"] == "step_ended"]
    assert ended == ["switch_map", "goto", "dwell", "goto", "dwell", "goto"]


def test_a_timetask_file_needs_the_points_of_its_paths(tmp_path: Path) -> None:
    plan = write(tmp_path, TIMETASK, "timeTask.json")
    result = invoke("mission", "run", plan, "--task", "autoRunTasks[0]", port=None)
    assert result.exit_code == ExitCode.USAGE, result.output
    assert "a timeTask.json needs the points of its paths" in result.output


def test_a_nav2_waypoint_file_runs(tmp_path: Path) -> None:
    path = tmp_path / "waypoints.yaml"
    path.write_text(
        "waypoints:\n  waypoint0:\n    pose: [1.0, 0.0, 0.0]\n"
        "    orientation: [1.0, 0.0, 0.0, 0.0]\n",
        encoding="utf-8",
    )
    result = invoke("--json", "mission", "run", str(path), "--sim", port=None)
    assert result.exit_code == 0, result.output
    ended = [e["step"]["ending"] for e in lines(result.stdout) if e["event"] == "step_ended"]
    assert ended[-1] == "reached"


def test_a_file_release(tmp_path: Path) -> None:
    go = tmp_path / "go"
    go.write_text("", encoding="utf-8")
    plan = write(tmp_path, LOBBY)
    result = invoke("mission", "run", plan, "--release", f"operator=file:{go}", port=None)
    assert result.exit_code == 0, result.output
    assert "steps[2].loop.steps[1] wait done" in result.stdout


def test_a_key_release(tmp_path: Path) -> None:
    plan = write(tmp_path, {"mission": "m", "steps": [{"wait": "operator"}, {"goto": 1}]})
    result = invoke("mission", "run", plan, "--release", "operator=key", port=None, input=b"\n")
    assert result.exit_code == 0, result.output


def test_sim_prints_the_timeline_of_the_whole_plan(tmp_path: Path) -> None:
    plan = write(tmp_path, LOBBY)
    result = invoke("mission", "run", plan, "--sim", port=None)
    assert result.exit_code == 0, result.output
    out = result.stdout.splitlines()
    assert out[0].split() == ["0.0", "s", "steps[0]", "goto", "started", "(attempt", "1)"]
    assert out[-1].split()[2:] == ["mission", "completed"]
    assert float(out[-1].split()[0]) > 37.0  # 30 s of dwell and three goals, in no time


def test_sim_plays_http_steps_on_the_simulators_http_face(tmp_path: Path) -> None:
    plan = write(
        tmp_path, {"mission": "m", "steps": [{"say": "hi"}, {"goto_pose": {"x": 1, "y": 0}}]}
    )
    result = invoke("--json", "mission", "run", plan, "--sim", port=None)
    assert result.exit_code == 0, result.output
    ended = [e["step"]["ending"] for e in lines(result.stdout) if e["event"] == "step_ended"]
    assert ended == ["done", "reached"]


def test_sim_stops_a_forever_loop_after_until(tmp_path: Path) -> None:
    forever = {
        "mission": "m",
        "steps": [{"loop": {"count": "forever", "steps": [{"goto": 1}, {"goto": 2}]}}],
    }
    result = invoke(
        "mission", "run", write(tmp_path, forever), "--sim", "--until", "600", port=None
    )
    assert result.exit_code == ExitCode.CANCELLED, result.output
    assert result.stdout.splitlines()[-1].split()[2:] == ["mission", "stopped"]


def test_a_journal_and_a_resume_that_is_refused(tmp_path: Path) -> None:
    plan, journal = write(tmp_path, {"mission": "m", "steps": [{"goto": 1}]}), tmp_path / "j.json"
    result = invoke("mission", "run", plan, "--journal", str(journal), port=None)
    assert result.exit_code == 0, result.output
    again = invoke("mission", "run", plan, "--journal", str(journal), "--resume", port=None)
    assert again.exit_code == ExitCode.USAGE, again.output
    assert "the mission completed; nothing to resume" in again.output


FLEET = """
[robots.alpha]
port = "sim://?speed=20"

[robots.beta]
port = "sim://?speed=20"
"""


def test_fleet_mission_run_runs_every_robot_and_prefixes_its_lines(tmp_path: Path) -> None:
    fleet = tmp_path / "fleet.toml"
    fleet.write_text(FLEET, encoding="utf-8")
    shared = write(tmp_path, {"mission": "shared", "steps": [{"goto": 1}]})
    own = write(tmp_path, {"mission": "own", "steps": [{"goto": 9}]}, "own.json")
    result = invoke(
        "--fleet", str(fleet), "fleet", "mission", "run", shared, "--per-robot", f"beta={own}",
        port=None,
    )  # fmt: skip
    assert result.exit_code == ExitCode.REJECTED, result.output  # beta's goal was refused
    out = result.stdout.splitlines()
    assert any(line.startswith("alpha: mission 'shared' completed") for line in out), out
    assert any(line.startswith("beta: mission 'own' failed") for line in out), out
    json_run = invoke("--fleet", str(fleet), "--json", "fleet", "mission", "run", shared, port=None)
    assert json_run.exit_code == 0, json_run.output
    assert {e["robot"] for e in lines(json_run.stdout)} == {"alpha", "beta"}


def test_fleet_mission_run_needs_a_fleet_file(tmp_path: Path) -> None:
    result = invoke("fleet", "mission", "run", write(tmp_path, LOBBY), port=None)
    assert result.exit_code == ExitCode.USAGE


def report(ending: str, last: str | None = None) -> MissionReport:
    step = {"path": "steps[0]", "name": None, "action": "goto", "ending": last or "reached",
            "started": 0, "ended": 1, "started_at": "2026-01-01T00:00:00Z",
            "ended_at": "2026-01-01T00:00:01Z", "attempts": 1, "distance_m": 0}  # fmt: skip
    return MissionReport.model_validate(
        {
            "mission": "m",
            "ending": ending,
            "steps": [step],
            "started": 0,
            "ended": 1,
            "started_at": "2026-01-01T00:00:00Z",
            "ended_at": "2026-01-01T00:00:01Z",
        }
    )


@pytest.mark.parametrize(
    ("ending", "last", "code"),
    [
        ("completed", None, 0), ("stopped", "stopped", 5), ("link lost", "link lost", 7),
        ("cancelled", "cancelled", 130), ("failed", "rejected", 3), ("failed", "aborted", 4),
        ("failed", "stalled", 4), ("failed", "timeout", 6), ("failed", "failed", 1),
    ],
)  # fmt: skip
def test_mission_exit_codes(ending: str, last: str | None, code: int) -> None:
    assert mission_exit_code(report(ending, last)) == code


@pytest.mark.parametrize(("sig", "code"), [(signal.SIGTERM, 143), (signal.SIGINT, 130)])
def test_a_signal_stops_the_mission_and_the_robot(
    tmp_path: Path, sig: signal.Signals, code: int
) -> None:
    plan = write(tmp_path, {"mission": "m", "steps": [{"goto": 2}, {"dwell": 600}]})
    process = start("--port", "sim://", "--json", "mission", "run", plan)
    assert process.stdout is not None
    read_until(process.stdout, '"step_started"')
    returncode, out, err = finish(process, sig)
    assert returncode == code, err
    events = lines(out)
    ended = [e for e in events if e.get("event") == "mission_ended"]
    assert ended[0]["report"]["ending"] == "cancelled"
    assert any(e.get("result") == "interrupted" and e.get("stop_sent") for e in events), out


PATROL: dict[str, Any] = {
    "mission": "patrol",
    "steps": [{"loop": {"count": 2, "steps": [{"goto": 1}, {"dwell": 5}, {"goto": 2}]}}],
}


def test_offload_prints_the_lines_of_a_run(tmp_path: Path) -> None:
    plan = write(tmp_path, PATROL)
    result = invoke("mission", "run", plan, "--sim", "--offload", port=None)
    assert result.exit_code == 0, result.output
    out = result.stdout.splitlines()
    assert out[0] == "steps[0] loop 1 of 2"
    assert out[1].startswith("steps[0].loop.steps[0] goto reached in ")
    assert out[2].startswith("steps[0].loop.steps[1] dwell done in ")
    assert out[4] == "steps[0] loop 2 of 2"
    assert out[-1].startswith("mission 'patrol' completed: 6 steps, 2 loops")
    json_run = invoke("--json", "mission", "run", plan, "--sim", "--offload", port=None)
    assert json_run.exit_code == 0, json_run.output
    events = lines(json_run.stdout)
    assert [e["event"] for e in events[:3]] == ["loop_started", "step_started", "step_ended"]
    assert events[2]["step"]["ending"] == "reached"
    assert events[2]["step"]["loops"] == {"steps[0]": 1}
    assert events[-1]["report"]["ending"] == "completed"
    assert events[-1]["report"]["loops_done"] == 2


def test_offload_of_a_forever_loop_stops_after_until(tmp_path: Path) -> None:
    forever = {"mission": "m", "steps": [{"loop": {"steps": [{"goto": 1}, {"goto": 2}]}}]}
    result = invoke(
        "mission", "run", write(tmp_path, forever), "--sim", "--offload", "--until", "120",
        port=None,
    )  # fmt: skip
    assert result.exit_code == ExitCode.CANCELLED, result.output
    assert result.stdout.splitlines()[-1].startswith("mission 'm' stopped: ")


def test_offload_of_a_mission_the_chain_cannot_run_exits_2_naming_every_problem(
    tmp_path: Path,
) -> None:
    plan = write(
        tmp_path, {"mission": "m", "steps": [{"say": "hi"}, {"goto": 1, "on_failure": "skip"}]}
    )
    result = invoke("--json", "mission", "run", plan, "--sim", "--offload", port=None)
    assert result.exit_code == ExitCode.USAGE, result.output
    assert [line["message"] for line in lines(result.stdout)] == [
        "mission 'm': steps[0]: say: the task chain has no speech action",
        "mission 'm': steps[1]: on_failure skip: the task chain ends at the first failed "
        "action (on_failure: abort)",
    ]


@pytest.mark.parametrize(
    ("args", "port", "message"),
    [
        ((), "sim://", "--offload needs the robot's task chain: an http:// or https://"),
        (("--sim", "--journal", "j.json"), None, "--journal, --resume and --release are for"),
    ],
    ids=["not http", "journal"],
)
def test_offload_usage_errors_exit_2(
    tmp_path: Path, args: tuple[str, ...], port: str | None, message: str
) -> None:
    result = invoke("mission", "run", write(tmp_path, PATROL), "--offload", *args, port=port)
    assert result.exit_code == ExitCode.USAGE, result.output
    assert message in result.output


def test_offload_to_the_http_face_of_a_simulator(
    tmp_path: Path, request: pytest.FixtureRequest
) -> None:
    robot: HttpServedSim = request.getfixturevalue("http_sim")
    # The robot is outside the command's loop: the real clock (as test_cli_served's).
    plan = write(tmp_path, {"mission": "m", "steps": [{"goto": 1}, {"dwell": 1}]})
    opened = invoke("nav", "start", port=robot.url, real_clock=True)
    assert opened.exit_code == 0, opened.output
    result = invoke(
        "--json", "mission", "run", plan, "--offload", port=robot.url, real_clock=True,
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    ended = [e["step"]["ending"] for e in lines(result.stdout) if e["event"] == "step_ended"]
    assert ended == ["reached", "done"]


def test_run_checks_the_plan_first_an_error_exits_2_before_anything_moves(
    tmp_path: Path,
) -> None:
    plan = write(tmp_path, {"mission": "m", "steps": [{"goto": 1}, {"dwell": 30, "timeout": 10}]})
    result = invoke("--json", "mission", "run", plan, port=None)
    assert result.exit_code == ExitCode.USAGE, result.output
    assert [line["message"] for line in lines(result.stdout)] == [
        f"{plan}: steps[1]: timeout 10 s ends the dwell of 30 s"
    ]  # no step_started: nothing moved
    fleet = tmp_path / "fleet.toml"
    fleet.write_text(FLEET, encoding="utf-8")
    on_fleet = invoke("--fleet", str(fleet), "fleet", "mission", "run", plan, port=None)
    assert on_fleet.exit_code == ExitCode.USAGE, on_fleet.output
    assert "steps[1]: timeout 10 s ends the dwell of 30 s" in on_fleet.output


def test_run_prints_the_plans_warnings_and_runs(tmp_path: Path) -> None:
    plan = write(tmp_path, {"mission": "m", "steps": [{"dwell": 0}, {"goto": 1}]})
    result = invoke("mission", "run", plan, port=None)
    assert result.exit_code == 0, result.output
    assert f"{plan}: warning: steps[0]: dwell 0 does nothing" in result.stderr
    assert result.stdout.splitlines()[-1].startswith("mission 'm' completed")
