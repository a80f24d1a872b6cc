"""MCAP on the command line: record, fleet record, decode, replay and sim://?replay=."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from mcap.reader import make_reader

from galileo_async import connect
from galileo_async.cli import ExitCode
from galileo_async.errors import InvalidArgument
from galileo_async.recording import read_recording, status_json
from galileo_async.sim import Simulator
from tests.cli.test_cli import invoke, json_lines
from tests.cli.test_cli_fleet import invoke as invoke_fleet

FLEET = """
[defaults]
first_status_timeout = 5

[robots.alpha]
port = "sim://?speed=20"

[robots.beta]
port = "sim://?speed=20&layout=v1"
"""


def record(path: Path, *more: str) -> None:
    result = invoke("record", str(path), *more, "--duration", "0.5", real_clock=True)
    assert result.exit_code == 0, result.output
    assert "statuses" in result.stdout
    assert "of 1 robot(s)" in result.stdout


def test_record_a_file_ending_in_mcap_writes_mcap(tmp_path: Path) -> None:
    path = tmp_path / "run.mcap"
    record(path)
    with path.open("rb") as stream:
        summary = make_reader(stream).get_summary()
    assert summary is not None
    assert {c.topic for c in summary.channels.values()} >= {"/robot/raw", "/robot/status"}
    decoded = invoke("--json", "decode", str(path))
    assert decoded.exit_code == 0, decoded.output
    lines = json_lines(decoded.stdout)
    found = lines[-1]["summary"]
    assert isinstance(found, dict)
    assert found["format"] == "mcap"
    assert found["robot"] == "robot"
    assert found["layout"] == "v2"
    assert found["frames"] == len(lines) - 1 > 5
    assert all("t" in line and "nav_status" in line for line in lines[:-1])


def test_record_mcap_by_option_and_decode_from_stdin(tmp_path: Path) -> None:
    path = tmp_path / "run.bin"
    record(path, "--mcap")
    data = path.read_bytes()
    assert data.startswith(b"\x89MCAP0\r\n")
    decoded = invoke("decode", "-", "--summary-only", input=data)
    assert decoded.exit_code == 0, decoded.output
    assert "format mcap" in decoded.stderr


def test_the_format_is_told_by_content_not_by_name(tmp_path: Path) -> None:
    capture = tmp_path / "capture.mcap"
    recorded = invoke("record", str(tmp_path / "c.glc"), "--duration", "0.3", real_clock=True)
    assert recorded.exit_code == 0
    capture.write_bytes((tmp_path / "c.glc").read_bytes())  # our own format, named .mcap
    decoded = invoke("decode", str(capture), "--summary-only")
    assert decoded.exit_code == 0, decoded.output
    assert "format recording" in decoded.stderr


def test_record_refuses_raw_with_mcap(tmp_path: Path) -> None:
    result = invoke("record", str(tmp_path / "x.mcap"), "--raw")
    assert result.exit_code == ExitCode.USAGE, result.output
    assert "exclude each other" in result.stderr


def test_decode_robot_wants_an_mcap_file(tmp_path: Path) -> None:
    capture = tmp_path / "raw.bin"
    capture.write_bytes(b"\xcd\xeb\xd7")
    result = invoke("decode", str(capture), "--robot", "alpha")
    assert result.exit_code == ExitCode.USAGE, result.output
    assert "--robot picks a robot of an MCAP recording" in result.stderr


def test_decode_a_bad_mcap_file_is_one_error_line(tmp_path: Path) -> None:
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(b"\x89MCAP0\r\n" + b"\x00" * 40)
    result = invoke("decode", str(bad))
    assert result.exit_code == ExitCode.ERROR, result.output
    assert "not a readable MCAP file" in result.stderr
    assert "Traceback" not in result.output


@pytest.fixture(scope="module")
def fleet_recording(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("fleet")
    fleet = folder / "fleet.toml"
    fleet.write_text(FLEET)
    path = folder / "fleet.mcap"
    result = invoke_fleet("--fleet", str(fleet), "fleet", "record", str(path), "--duration", "1")
    assert result.exit_code == 0, result.output
    assert "of 2 robot(s)" in result.stdout
    return path


def test_fleet_record_writes_a_channel_set_per_robot(fleet_recording: Path) -> None:
    recording = read_recording(fleet_recording)
    assert sorted(recording.robots) == ["alpha", "beta"]
    assert all(robot.raw and robot.statuses for robot in recording.robots.values())
    decoded = invoke("--json", "decode", str(fleet_recording), "--robot", "beta")
    assert decoded.exit_code == 0, decoded.output
    summary = json_lines(decoded.stdout)[-1]["summary"]
    assert isinstance(summary, dict)
    assert summary["robot"] == "beta"
    assert summary["layout"] == "v1"
    ambiguous = invoke("decode", str(fleet_recording))
    assert ambiguous.exit_code == ExitCode.USAGE, ambiguous.output
    assert "pick one of alpha, beta" in ambiguous.stderr


def test_replay_of_a_fleet_recording_names_the_robots(fleet_recording: Path) -> None:
    result = invoke("replay", str(fleet_recording), "--tcp", "127.0.0.1:0", port=None)
    assert result.exit_code == ExitCode.USAGE, result.output
    assert "pick one of alpha, beta" in result.stderr
    unknown = invoke("replay", str(fleet_recording), "--robot", "gamma", port=None)
    assert unknown.exit_code == ExitCode.USAGE, unknown.output
    assert "no robot 'gamma' (robots: alpha, beta)" in unknown.stderr


async def test_sim_url_replays_a_robot_of_a_fleet_recording(fleet_recording: Path) -> None:
    expected = [values for _t, values in read_recording(fleet_recording).robot("beta").statuses]
    async with connect(f"sim://?replay={fleet_recording}&robot=beta&speed=50") as robot:
        status = robot.status
        assert status is not None
        assert status.layout.value == "v1"
        assert status_json(status) in expected
    with pytest.raises(InvalidArgument, match="pick one of alpha, beta"):
        Simulator.from_url(f"sim://?replay={fleet_recording}")
    with pytest.raises(InvalidArgument, match="robot= picks the robot of a replay= recording"):
        Simulator.from_url("sim://?robot=beta")


def test_fleet_record_without_a_fleet_file_is_a_usage_error(tmp_path: Path) -> None:
    result = invoke_fleet("fleet", "record", str(tmp_path / "x.mcap"))
    assert result.exit_code == ExitCode.USAGE, result.output
    assert json.dumps("fleet commands need a fleet file")[1:-1] in result.output


def _has_a_status(path: Path) -> bool:
    """``path`` holds at least one recorded status (read as a file cut short)."""
    try:
        return any(robot.statuses for robot in read_recording(path).robots.values())
    except (InvalidArgument, OSError):
        return False


@pytest.mark.parametrize("signal_name", ["SIGTERM", "SIGINT"])
def test_record_ended_by_a_signal_finishes_the_file(tmp_path: Path, signal_name: str) -> None:
    path = tmp_path / "signal.mcap"
    process = subprocess.Popen(
        [sys.executable, "-m", "galileo_async", "--port", "sim://?speed=20", "record", str(path)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        deadline = time.monotonic() + 30
        # Another process: a status readable from its file is the sign that it records.
        while not _has_a_status(path) and time.monotonic() < deadline:
            time.sleep(0.05)
        process.send_signal(getattr(signal, signal_name))
        out, err = process.communicate(timeout=30)
    finally:
        process.kill()
    assert process.returncode == 0, err
    assert "statuses" in out
    with path.open("rb") as stream:
        summary = make_reader(stream).get_summary()
    assert summary is not None
    assert summary.statistics is not None
    assert summary.statistics.message_count > 0
