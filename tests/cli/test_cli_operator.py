"""The ``galileo`` command as an operator meets it: one line per failure, Ctrl-C, progress."""

from __future__ import annotations

import datetime
import json
import signal
import socket
import struct
import subprocess
import sys
from pathlib import Path

import pytest

from galileo_async.models import float32_decimal

GALILEO = [sys.executable, "-m", "galileo_async"]
#: Bound on every run, seconds.
WAIT = 60
#: A goal that takes seconds: the simulator at half speed, target 3 is 3.6 m away.
SLOW_SIM = "sim://?speed=0.5"


def galileo(*args: str, stdin: str | None = None) -> subprocess.CompletedProcess[str]:
    """Run ``galileo ARGS`` to its end; stdout and stderr captured (neither is a terminal)."""
    return subprocess.run(
        [*GALILEO, *args], capture_output=True, text=True, timeout=WAIT, input=stdin, check=False
    )


def one_error_line(result: subprocess.CompletedProcess[str]) -> str:
    """The single ``error: …`` line of a failed run (no traceback)."""
    assert "Traceback" not in result.stderr, result.stderr
    errors = [line for line in result.stderr.splitlines() if line.startswith("error:")]
    assert len(errors) == 1, result.stderr
    return errors[0]


# --- item 1: no traceback, ever --------------------------------------------------------------


@pytest.mark.parametrize(
    "args",
    [["status", "--watch", "--interval", "0.02"], ["--json", "monitor"]],
    ids=["status --watch", "--json monitor"],
)
def test_a_reader_that_closes_stdout_ends_the_command_quietly(args: list[str]) -> None:
    with subprocess.Popen(
        [*GALILEO, *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    ) as process:
        assert process.stdout is not None
        assert process.stderr is not None
        assert process.stdout.readline()  # like `| head -1`: one line, then the pipe closes
        process.stdout.close()
        stderr = process.stderr.read()
        assert process.wait(WAIT) == 0
    assert "Traceback" not in stderr, stderr
    assert "Error" not in stderr, stderr


@pytest.mark.parametrize(
    ("args", "code", "words"),
    [
        (["discover", "--udp-port", "70000", "-t", "0.1"], 2, ["65535"]),
        (["discover", "--udp-port", "-1", "-t", "0.1"], 2, ["--udp-port", "0"]),
        (["sim", "--tcp", "127.0.0.1:70000"], 2, ["port 70000", "0..65535"]),
        (["sim", "--tcp", "nosuchhost.invalid:7000"], 7, ["nosuchhost.invalid", "unknown host"]),
    ],
)
def test_bad_addresses_are_one_line(args: list[str], code: int, words: list[str]) -> None:
    result = galileo(*args)
    assert result.returncode == code, result.stderr
    assert "Traceback" not in result.stderr, result.stderr
    assert all(word in result.stderr for word in words), result.stderr


def test_the_library_refuses_a_discovery_port_out_of_range() -> None:
    import asyncio

    from galileo_async.errors import InvalidArgument
    from galileo_async.ros.discovery import discover

    with pytest.raises(InvalidArgument, match="65535"):
        asyncio.run(discover(0.1, port=70000))


def test_a_port_in_use_says_so_with_a_hint() -> None:
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        result = galileo("sim", "--tcp", f"127.0.0.1:{port}")
    assert result.returncode == 7
    line = one_error_line(result)
    assert f"127.0.0.1:{port} is already in use" in line
    assert "port 0" in line
    assert "Errno" not in line


@pytest.mark.parametrize("port", ["foo://x", "serial:///dev/ttyS0"])
def test_an_unknown_scheme_is_refused_with_the_known_ones(port: str) -> None:
    result = galileo("--port", port, "status")
    assert result.returncode == 2
    line = one_error_line(result)
    assert "unknown URL scheme" in line
    assert "serial port" not in line
    for scheme in ("socket://", "udp://", "ros://", "sim://", "rfc2217://", "loop://"):
        assert scheme in line


def test_a_host_and_port_gets_the_socket_hint() -> None:
    result = galileo("--port", "127.0.0.1:7100", "status")
    assert result.returncode == 7
    assert "write socket://127.0.0.1:7100" in one_error_line(result)


def test_a_missing_device_says_errno_once() -> None:
    result = galileo("--port", "/dev/nonexistent", "status")
    assert result.returncode == 7
    line = one_error_line(result)
    assert line.count("No such file") == 1
    assert "Errno" not in line


def test_json_errors_are_one_object_on_stdout() -> None:
    result = galileo("--json", "--port", "/dev/nonexistent", "status")
    assert result.returncode == 7
    assert "error:" not in result.stderr
    (line,) = result.stdout.splitlines()
    data = json.loads(line)
    assert data["error"] == "GalileoConnectionError"
    assert data["exit_code"] == 7
    assert "/dev/nonexistent" in data["message"]
    usage = json.loads(galileo("--json", "shutdown").stdout)
    assert usage == {
        "error": "usage",
        "message": "shutdown powers the navigation computer off; pass --yes to confirm",
        "exit_code": 2,
    }


def test_a_goto_timeout_in_json_names_the_target_and_its_last_distance() -> None:
    result = galileo("--json", "--port", SLOW_SIM, "goto", "3", "--timeout", "2")
    assert result.returncode == 6, result.stderr
    data = json.loads(result.stdout)
    assert data["result"] == "timeout"
    assert data["target_id"] == 3
    assert isinstance(data["distance"], float)
    assert 0 < data["distance"] < 4
    assert data["distance"] == round(data["distance"], 3)


# --- item 2: Ctrl-C tells what happened ------------------------------------------------------


def interrupted_goto(*args: str, started: str) -> tuple[int, str, str]:
    """Run ``goto 3``, send SIGINT once a stderr line contains ``started``; (code, out, err)."""
    with subprocess.Popen(
        [*GALILEO, *args, "--port", SLOW_SIM, "goto", "3"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    ) as process:
        assert process.stderr is not None
        seen = []
        for line in process.stderr:
            seen.append(line)
            if started in line:
                break
        else:
            pytest.fail("".join(seen))
        process.send_signal(signal.SIGINT)
        out, err = process.communicate(timeout=WAIT)
    return process.returncode, out, "".join(seen) + err


def test_ctrl_c_in_goto_says_the_goal_was_cancelled_and_where_the_robot_is() -> None:
    code, out, err = interrupted_goto(started="working")
    assert code == 130
    last = err.splitlines()[-1]
    assert last.startswith("interrupted by SIGINT: goal 3 cancelled (i 2 sent), stop sent"), err
    assert "; robot at (" in last, err
    assert out == ""


def test_ctrl_c_in_goto_with_json_prints_a_json_line() -> None:
    code, out, _ = interrupted_goto("-v", "--json", started="goal 3 accepted")
    assert code == 130
    data = json.loads(out)
    assert data["result"] == "interrupted"
    assert data["target_id"] == 3
    assert data["cancel_sent"] is True
    assert data["signal"] == "SIGINT"
    assert data["stop_sent"] is True
    assert set(data["pose"]) == {"x", "y", "degrees"}


# --- item 3: progress without a terminal -----------------------------------------------------


def test_goto_without_a_terminal_prints_plain_progress_lines() -> None:
    result = galileo("--port", "sim://?speed=2", "goto", "3")
    assert result.returncode == 0, result.stderr
    progress = [line for line in result.stderr.splitlines() if line.startswith("goto 3 ·")]
    assert len(progress) >= 2, result.stderr
    assert any("working" in line for line in progress)
    assert "\x1b" not in result.stderr  # no terminal control sequences


# --- item 4: numbers for humans --------------------------------------------------------------


def decimals(value: float) -> int:
    text = repr(value)
    return len(text.partition(".")[2])


def test_json_status_is_rounded_as_shown() -> None:
    # A served simulator keeps the pose and power a goal left: full-precision floats.
    with subprocess.Popen(
        [*GALILEO, "sim", "--tcp", "127.0.0.1:0", "--speed", "5"],
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
    ) as server:
        assert server.stdout is not None
        url = server.stdout.readline().strip()
        try:
            # Stopped half way (timeout, exit 6): wherever it is, not on a round number.
            moved = galileo("--port", url, "goto", "3", "--start-nav", "--timeout", "0.6")
            assert moved.returncode == 6, moved.stderr
            status = json.loads(galileo("--json", "--port", url, "status").stdout)["status"]
        finally:
            server.send_signal(signal.SIGINT)
            assert server.wait(WAIT) == 0
    assert decimals(status["power"]) <= 2
    for key in ("current_pose_x", "current_pose_y", "current_angle", "target_distance"):
        assert decimals(status[key]) <= 3, key


def test_the_status_table_shows_volts_to_hundredths() -> None:
    table = galileo("--port", "sim://?speed=20", "status").stdout
    power = next(line for line in table.splitlines() if line.startswith("power"))
    assert power.split()[-1] in ("25.00", "24.99", "24.98")


# --- item 5: time ----------------------------------------------------------------------------


def utc(text: str) -> datetime.datetime:
    assert text.endswith("Z")
    return datetime.datetime.fromisoformat(text.removesuffix("Z") + "+00:00")


def test_every_json_status_line_carries_a_utc_timestamp() -> None:
    before = datetime.datetime.now(datetime.timezone.utc) - datetime.timedelta(seconds=1)
    result = galileo("--json", "status", "--watch", "--count", "2", "--interval", "0.02")
    lines = [json.loads(line) for line in result.stdout.splitlines()]
    assert len(lines) == 2
    once = json.loads(galileo("--json", "status").stdout)
    after = datetime.datetime.now(datetime.timezone.utc) + datetime.timedelta(seconds=1)
    for line in [*lines, once]:
        assert before <= utc(line["time"]) <= after


def test_log_file_gets_timestamped_unwrapped_debug_lines(tmp_path: Path) -> None:
    log_file = tmp_path / "galileo.log"
    result = galileo("--log-file", str(log_file), "--port", "sim://?speed=5", "goto", "3")
    assert result.returncode == 0
    assert "DEBUG" not in result.stderr  # without -v nothing is logged on stderr
    lines = log_file.read_text(encoding="utf-8").splitlines()
    assert any("goal 3 accepted" in line for line in lines)
    for line in lines:
        stamp, level, _ = line.split(" ", 2)
        utc(stamp)
        assert level in ("DEBUG", "INFO", "WARNING", "ERROR")
    assert max(len(line) for line in lines) > 80  # one record is one line, however long


def test_verbose_logs_to_a_file_are_not_wrapped() -> None:
    result = galileo("-vv", "--port", "sim://?speed=5", "status")
    assert result.returncode == 0
    frames = [line for line in result.stderr.splitlines() if "transports.frames" in line]
    assert frames
    assert all(" rx " in line or " tx " in line for line in frames)
    assert max(len(line) for line in frames) > 80


# --- item 13 ---------------------------------------------------------------------------------


def test_cancel_without_a_goal_says_no_goal_was_running() -> None:
    result = galileo("--port", "sim://", "cancel")
    assert result.returncode == 0
    assert result.stdout.strip() == "no goal was running"


def test_decode_raw_keeps_every_bit(tmp_path: Path) -> None:
    capture = tmp_path / "capture.glc"
    recorded = galileo("--port", "sim://?power=24.79", "record", str(capture), "--duration", "0.3")
    assert recorded.returncode == 0, recorded.stderr
    shown = json.loads(galileo("decode", str(capture)).stdout.splitlines()[-1])
    exact = json.loads(galileo("decode", "--raw", str(capture)).stdout.splitlines()[-1])
    assert decimals(shown["power"]) <= 2
    # The float32 of 24.79 reads as 24.79, not 24.790000915527344, and keeps its bits.
    assert exact["power"] == shown["power"] == 24.79
    wire = struct.unpack("<f", struct.pack("<f", 24.79))[0]
    assert float32_decimal(wire) == exact["power"]


@pytest.mark.parametrize("port", ["socket://nosuchhost.invalid:7000", "udp://nosuchhost.invalid"])
def test_an_unknown_host_is_named(port: str) -> None:
    result = galileo("--port", port, "status")
    assert result.returncode == 7
    line = one_error_line(result)
    assert "nosuchhost.invalid" in line
    assert "unknown host" in line
