"""Where the CLI's robot is: the simulator by default says so, an empty port is refused."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from galileo_async.cli import ExitCode
from galileo_async.cli.runner import SIMULATOR_NOTICE
from tests.cli.test_cli import FAST, invoke, json_lines

GALILEO = [sys.executable, "-m", "galileo_async"]
#: Bound on one CLI run, seconds.
RUN_TIMEOUT = 60.0


def galileo(
    *args: str, port_env: str | None = None, cwd: Path | None = None
) -> subprocess.CompletedProcess[str]:
    """Run ``python -m galileo_async args…``; GALILEO_PORT set to ``port_env`` or unset."""
    env = {key: value for key, value in os.environ.items() if key != "GALILEO_PORT"}
    if port_env is not None:
        env["GALILEO_PORT"] = port_env
    return subprocess.run(
        [*GALILEO, *args], env=env, capture_output=True, text=True, timeout=RUN_TIMEOUT, cwd=cwd
    )


def notices(stderr: str) -> int:
    return stderr.splitlines().count(SIMULATOR_NOTICE)


@pytest.mark.parametrize(
    "args",
    [["cancel"], ["nav", "stop"], ["status"], ["--json", "status"], ["record", "{tmp}"]],
    ids=["cancel", "nav-stop", "status", "status-json", "record"],
)
def test_the_default_simulator_says_so_once_on_stderr(args: list[str], tmp_path: Path) -> None:
    args = [arg.format(tmp=tmp_path / "capture.glc") for arg in args]
    if args[0] == "record":
        args += ["--duration", "0.1"]
    done = galileo(*args)
    assert done.returncode == 0, done.stderr
    assert notices(done.stderr) == 1, done.stderr
    assert SIMULATOR_NOTICE not in done.stdout  # the data on stdout stays clean


def test_the_default_simulator_is_named_in_json_output() -> None:
    status = galileo("--json", "status")
    assert json.loads(status.stdout)["port"] == "sim://"
    cancelled = galileo("--json", "cancel")
    done = {
        "port": "sim://",
        "result": "ok",
        "done": "no goal was running",
        "goal_was_running": False,
    }
    assert json.loads(cancelled.stdout) == done


@pytest.mark.parametrize("given", ["option", "environment"])
def test_a_port_given_gets_no_notice_and_is_named_in_json(given: str) -> None:
    if given == "option":
        done = galileo("--port", FAST, "--json", "cancel", port_env="")
    else:
        done = galileo("--json", "cancel", port_env=FAST)
    assert done.returncode == 0, done.stderr
    assert notices(done.stderr) == 0, done.stderr
    assert json.loads(done.stdout)["port"] == FAST


@pytest.mark.parametrize(
    ("args", "port_env", "named"),
    [
        (["cancel"], "", "GALILEO_PORT is empty"),
        (["--port", "", "cancel"], None, "--port is empty"),
        (["--port", " ", "nav", "start"], None, "--port is empty"),
        (["--json", "status"], "", "GALILEO_PORT is empty"),
        (["record", "never-written.glc"], "", "GALILEO_PORT is empty"),
        (["--port", "", "demo"], None, "--port is empty"),
    ],
)
def test_an_empty_port_is_a_usage_error(
    args: list[str], port_env: str | None, named: str, tmp_path: Path
) -> None:
    done = galileo(*args, port_env=port_env, cwd=tmp_path)
    assert done.returncode == ExitCode.USAGE, done.stderr
    if "--json" in args:  # the error is the JSON object on stdout
        error = json.loads(done.stdout)
        assert error["message"].startswith(f"{named}: name the robot's port")
        assert error["exit_code"] == ExitCode.USAGE
    else:
        assert done.stdout == ""
        assert done.stderr.startswith(f"error: {named}: name the robot's port"), done.stderr
    assert notices(done.stderr) == 0
    assert list(tmp_path.iterdir()) == []  # record did not even create its file


def test_the_demo_is_the_simulator_by_design_and_prints_no_notice() -> None:
    done = galileo("demo", "--speed", "100")
    assert done.returncode == 0, done.stderr
    assert notices(done.stderr) == 0
    assert "galileo demo · sim://" in done.stdout  # its summary names the simulator


def test_commands_that_open_no_port_ignore_an_empty_one(tmp_path: Path) -> None:
    capture = tmp_path / "empty.bin"
    capture.write_bytes(b"")
    done = galileo("decode", str(capture), "--summary-only", port_env="")
    assert done.returncode == 0, done.stderr


def test_every_json_line_of_a_stream_names_the_port() -> None:
    watch = invoke("--json", "status", "--watch", "--count", "3", "--interval", "0.05")
    assert watch.exit_code == 0, watch.output
    monitor = invoke("--json", "monitor", "--duration", "1.2")
    assert monitor.exit_code == 0, monitor.output
    for result in (watch, monitor):
        lines = json_lines(result.stdout)
        assert lines
        assert {line["port"] for line in lines} == {FAST}
