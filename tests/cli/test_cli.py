"""The galileo CLI against the embedded simulator (sim://), through typer's CliRunner."""

from __future__ import annotations

import asyncio
import contextlib
import json
import socket
from collections.abc import AsyncIterator, Coroutine, Iterator
from pathlib import Path
from typing import Any

import anyio
import pytest
from typer.testing import CliRunner, Result

from galileo_async import connect
from galileo_async.cli import ExitCode, app, connectors
from galileo_async.testing import VirtualClock
from tests.cli.test_cli_served import WAIT, ServedSim, serving

FAST = "sim://?speed=20"
DOCUMENT = "sim://?speed=20&firmware=document"
#: A simulator whose every connection drops after one simulated second (50 ms real).
DROPPING = FAST + "&disconnect_after=1"


def invoke(
    *args: str, port: str | None = FAST, input: bytes | None = None, real_clock: bool = False
) -> Result:
    """Run ``galileo [--port port] args…`` in-process; GALILEO_PORT cleared.

    With only sim:// addresses (in the command's own loop) or none, the command's event loop
    runs on the virtual clock, unless ``real_clock``; with any other address, ``port`` or
    one in ``args`` (``-p URL``), on the real one: a virtual clock would jump to each timeout
    while the loop waits for an answer from outside it. ``record`` takes the real clock:
    it writes through anyio's worker threads, which a VirtualClock does not wait for (it
    would jump to the --duration deadline meanwhile).
    """
    runner = CliRunner()
    full = (["--port", port] if port is not None else []) + list(args)
    virtual = not real_clock and all(a.startswith("sim://") for a in addresses(full))
    with on_the_virtual_clock() if virtual else contextlib.nullcontext():
        return runner.invoke(app, full, input=input, env={"GALILEO_PORT": None, "COLUMNS": "120"})


def addresses(args: list[str]) -> list[str]:
    """Every address a command line names: each --port or -p value, and every other URL."""
    found = []
    for before, arg in zip(["", *args], args, strict=False):
        if arg.startswith("--port="):
            found.append(arg.removeprefix("--port="))
        elif before in ("--port", "-p") or "://" in arg:
            found.append(arg)
    return found


@contextlib.contextmanager
def on_the_virtual_clock() -> Iterator[None]:
    """Every asyncio.run() meanwhile runs its coroutine on a VirtualClock (the CLI's one loop)."""
    real_run = asyncio.run

    async def virtually(main: Coroutine[Any, Any, Any]) -> Any:
        clock = VirtualClock.install()
        try:
            return await main
        finally:
            clock.release()

    def run(main: Coroutine[Any, Any, Any], **kwargs: Any) -> Any:
        return real_run(virtually(main), **kwargs)

    asyncio.run = run  # type: ignore[assignment]
    try:
        yield
    finally:
        asyncio.run = real_run


def json_lines(text: str) -> list[dict[str, object]]:
    return [json.loads(line) for line in text.splitlines() if line.startswith("{")]


@pytest.fixture
def served() -> Iterator[ServedSim]:
    yield from serving(20.0)


def test_invoke_takes_the_real_clock_for_an_address_outside_the_process() -> None:
    assert addresses(["--port", FAST, "status"]) == [FAST]
    assert addresses(["mission", "schema"]) == []
    http = "http://127.0.0.1:3546"
    assert addresses(["mission", "check", "a.yaml", "-p", http]) == [http]
    assert addresses(["--port=socket://h:1", "status"]) == ["socket://h:1"]
    assert addresses(["--port", "/dev/ttyUSB0", "status"]) == ["/dev/ttyUSB0"]
    assert addresses(["--port", FAST, "mission", "check", "a.yaml", "--port", http]) == [
        FAST,
        http,
    ]


def test_help_lists_every_command() -> None:
    result = invoke("--help", port=None)
    assert result.exit_code == 0
    for name in (
        "status", "monitor", "nav", "goto", "goto-point", "stop", "pause", "resume", "cancel",
        "rotate", "teleop", "patrol", "map", "charge", "shutdown", "send", "decode",
        "record", "ports", "sim", "demo",
    ):  # fmt: skip
        assert f" {name} " in result.stdout


def test_default_port_is_the_simulator() -> None:
    result = invoke("--json", "status", port=None)
    assert result.exit_code == 0, result.output
    data = json.loads(result.stdout)
    assert data["status"]["layout"] == "v2"
    assert data["link"]["frames"] >= 1


def test_status_table_shows_every_field() -> None:
    result = invoke("status")
    assert result.exit_code == 0, result.output
    assert "nav_status" in result.stdout
    assert "closed (0)" in result.stdout
    assert "busy_status" in result.stdout


def test_status_layout_option_pins_decoder_and_sim() -> None:
    result = invoke("--layout", "v1", "status", "--json")
    assert result.exit_code == 0, result.output
    status = json.loads(result.stdout)["status"]
    assert status["layout"] == "v1"
    assert status["map_status"] is None  # v1 lacks it: unknown, never zero


def test_bad_layout_is_a_usage_error() -> None:
    result = invoke("--layout", "v9", "status")
    assert result.exit_code == ExitCode.USAGE
    assert "v9" in result.output


def test_status_watch_prints_count_lines() -> None:
    result = invoke("status", "--watch", "--count", "3", "--interval", "0.05", "--json")
    assert result.exit_code == 0, result.output
    lines = json_lines(result.stdout)
    assert len(lines) == 3
    stamps = [line["status"]["time_stamp"] for line in lines]  # type: ignore[index]
    assert stamps == sorted(stamps)


def test_monitor_dashboard_runs_for_duration() -> None:
    result = invoke("monitor", "--duration", "0.3")
    assert result.exit_code == 0, result.output
    for panel in ("galileo monitor", "states", "pose & speed", "goal", "link", "recent events"):
        assert panel in result.stdout


def test_monitor_json_reports_events_and_status(served: ServedSim) -> None:
    # A goal runs on the served robot (driven from the simulator's thread) while the
    # monitor watches it: its goal events must come out as JSON lines.
    driving = served.run_soon(_drive_goal(served, target_id=0))
    result = invoke("--json", "monitor", "--duration", "2", port=served.url)
    driving.result(WAIT)
    assert result.exit_code == 0, result.output
    lines = json_lines(result.stdout)
    snapshots = [line for line in lines if "status" in line]
    assert snapshots
    assert "link" in snapshots[0]
    events = [(line["event"], line.get("target_id")) for line in lines if "event" in line]
    assert ("GoalAccepted", 0) in events
    assert ("GoalReached", 0) in events
    assert events.index(("GoalAccepted", 0)) < events.index(("GoalReached", 0))
    reached = next(line for line in lines if line.get("event") == "GoalReached")
    assert isinstance(reached["distance"], float)
    assert abs(reached["distance"]) <= 0.3
    assert isinstance(reached["t"], float)


async def _drive_goal(served: ServedSim, target_id: int) -> None:
    """Once the monitor is connected, open navigation and go to ``target_id`` (sim's loop)."""
    with anyio.fail_after(WAIT):
        while served.state.connections < 1:  # noqa: ASYNC110 - the simulator has no notification
            await anyio.sleep(0.005)
        async with connect(served.url) as robot:
            await robot.start_navigation()
            await robot.goto(target_id)


def test_monitor_json_reports_a_dropping_link() -> None:
    # Every connection of this simulator drops after one simulated second; monitor reconnects.
    result = invoke("--json", "monitor", "--duration", "0.5", port=DROPPING)
    assert result.exit_code == 0, result.output
    events = [line["event"] for line in json_lines(result.stdout) if "event" in line]
    assert "ConnectionLost" in events
    assert "ConnectionRestored" in events
    assert events.index("ConnectionLost") < events.index("ConnectionRestored")


def test_status_watch_reports_link_loss_and_reconnects() -> None:
    result = invoke("status", "--watch", "--count", "10", "--interval", "0.05", port=DROPPING)
    assert result.exit_code == 0, result.output
    lost = next(line for line in result.stderr.splitlines() if "connection lost" in line)
    assert lost.endswith("; reconnecting…")
    assert "connection restored" in result.stderr
    assert len(result.stdout.splitlines()) == 10


def test_status_watch_json_reports_link_events_as_lines() -> None:
    args = ("--json", "status", "--watch", "--count", "10", "--interval", "0.05")
    result = invoke(*args, port=DROPPING)
    assert result.exit_code == 0, result.output
    lines = json_lines(result.stdout)
    assert len([line for line in lines if "status" in line]) == 10
    lost = [line for line in lines if line.get("event") == "ConnectionLost"]
    assert lost
    assert isinstance(lost[0]["reason"], str)
    assert lost[0]["reason"]
    assert {"port": DROPPING, "event": "ConnectionRestored"} in [
        {key: value for key, value in line.items() if key not in ("time", "t")} for line in lines
    ]


def test_status_watch_without_reconnect_exits_on_link_loss() -> None:
    args = ("status", "--watch", "--no-reconnect", "--interval", "0.05")
    result = invoke(*args, port=DROPPING)
    assert result.exit_code == ExitCode.CONNECTION, result.output
    assert "connection lost" in result.stderr  # the link event, then the error line
    assert result.stderr.strip().splitlines()[-1].startswith("error: ConnectionLost: ")
    assert "Traceback" not in result.output


def test_nav_start_and_stop() -> None:
    assert invoke("nav", "start").stdout.strip() == "navigation open, visual initialised"
    result = invoke("nav", "stop")
    assert result.exit_code == 0
    assert "navigation closed" in result.stdout


def test_goto_arrives_with_exit_code_zero() -> None:
    result = invoke("goto", "0")
    assert result.exit_code == ExitCode.OK, result.output
    assert "arrived at target 0" in result.stdout
    assert "starting navigation" in result.stderr  # sim:// opens navigation by itself


def test_goto_json_result() -> None:
    result = invoke("--json", "goto", "2")
    assert result.exit_code == 0, result.output
    (data,) = json_lines(result.stdout)
    assert data["result"] == "arrived"
    assert data["target_id"] == 2
    assert isinstance(data["elapsed"], float)
    assert data["already_there"] is False


def test_goto_rejected_exit_code() -> None:
    # Document firmware shows an invalid id as target_status 3 with the id updated.
    result = invoke("goto", "42", "--json", port=DOCUMENT)
    assert result.exit_code == ExitCode.REJECTED, result.output
    assert json_lines(result.stdout)[0]["result"] == "rejected"


def test_goto_aborted_exit_code() -> None:
    result = invoke("goto", "1", port=FAST + "&planner_abort=next")
    assert result.exit_code == ExitCode.ABORTED, result.output
    assert "GoalAborted" in result.stderr


def test_goto_timeout_exit_code_and_one_line() -> None:
    result = invoke("goto", "1", "--timeout", "0.3", port="sim://?speed=2")
    assert result.exit_code == ExitCode.TIMEOUT, result.output
    assert "Traceback" not in result.output
    lines = [line for line in result.stderr.splitlines() if not line.startswith("goto 1 · ")]
    assert len(lines) == 2  # "starting navigation…" + the error (and progress lines)


def test_goto_without_navigation_is_not_ready() -> None:
    result = invoke("goto", "1", "--no-start-nav")
    assert result.exit_code == ExitCode.NOT_READY
    assert result.stderr.startswith("error: NotReady: ")
    assert "nav start" in result.stderr


def test_goto_bad_id_is_a_usage_error() -> None:
    assert invoke("goto", "300").exit_code == ExitCode.USAGE


def test_goto_negative_id_reaches_the_range_check() -> None:
    result = invoke("goto", "-1")
    assert result.exit_code == ExitCode.USAGE
    assert "no such option" not in result.output.lower()
    assert "greater than or equal to 0" in result.output


def test_connection_error_exit_code() -> None:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        port = sock.getsockname()[1]  # bound, not listening: connection refused
        result = invoke("status", port=f"socket://127.0.0.1:{port}")
    assert result.exit_code == ExitCode.CONNECTION
    assert "GalileoConnectionError" in result.stderr
    assert "Traceback" not in result.output


def test_verbose_shows_the_traceback() -> None:
    result = invoke("-v", "goto", "1", "--no-start-nav")
    assert result.exit_code == ExitCode.NOT_READY
    assert "Traceback" in result.stderr


def test_very_verbose_logs_raw_frames() -> None:
    result = invoke("-vv", "send", "Stop")
    assert result.exit_code == 0, result.output
    assert "galileo_async.transports.frames" in result.stderr
    assert "cd eb d7" in result.stderr


def test_goto_point_with_negative_coordinates() -> None:
    result = invoke("goto-point", "-1.5", "-2")
    assert result.exit_code == 0, result.output
    assert "arrived at target 6" in result.stdout  # first dynamic id after six map targets


def test_goal_commands_without_a_goal_are_not_ready() -> None:
    for command in ("pause", "resume"):
        result = invoke(command)
        assert result.exit_code == ExitCode.NOT_READY, (command, result.output)


def test_cancel_without_a_goal_is_fine() -> None:
    result = invoke("cancel")
    assert result.exit_code == 0
    assert result.stdout == "no goal was running\n"


def test_rotate_ignored_by_real_firmware_times_out() -> None:
    result = invoke("rotate", "90", "--timeout", "1")
    assert result.exit_code == ExitCode.TIMEOUT
    lines = result.stderr.strip().splitlines()
    error = lines[-1]
    # Said before the wait, so the user knows what the pause is about (a progress line
    # may follow it under load: at most one a second).
    notice = lines[-2] if lines[-2].startswith("rotate: ") else lines[-3]
    assert notice.startswith("rotate: waiting up to 1 s for angle_goal_status")
    assert "many firmware versions ignore the rotate command 'a'" in notice
    assert error.startswith("error: ")


def test_rotate_default_timeout_is_short() -> None:
    result = invoke("rotate", "--help")
    assert result.exit_code == 0
    assert "default: 10.0" in result.stdout


def test_rotate_in_document_mode_with_negative_angle() -> None:
    result = invoke("rotate", "-90", port=DOCUMENT)
    assert result.exit_code == 0, result.output
    assert "rotated to -90°" in result.stdout


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (("patrol", "start", "--dwell", "2"), "patrol running"),
        (("patrol", "stop"), "patrol stopped"),
        (("map", "start"), "mapping"),
        (("map", "save"), "map save sent"),
        (("map", "update"), "map update sent"),
        (("charge", "start"), "docking"),
        (("charge", "save-dock"), "dock position saved"),
        (("shutdown", "--yes"), "shutdown sent"),
    ],
)
def test_simple_commands(args: tuple[str, ...], expected: str) -> None:
    result = invoke(*args)
    assert result.exit_code == 0, result.output
    assert result.stdout.strip() == expected


def test_charge_start_help_says_it_is_the_local_docking() -> None:
    result = invoke("charge", "start", "--help")
    assert result.exit_code == 0
    text = " ".join(word for word in result.stdout.split() if word != "│")  # rich's box
    assert "local infrared docking only" in text
    assert "near the dock with navigation open" in text


def test_shutdown_needs_yes() -> None:
    result = invoke("shutdown")
    assert result.exit_code == ExitCode.USAGE
    assert "--yes" in result.stderr


@pytest.mark.parametrize(
    ("args", "wire"),
    [
        (("Goto", "3"), "cd eb d7 02 67 03"),
        (("start-navigation",), "cd eb d7 02 6d 00"),
        (("Stop",), "cd eb d7 02 73 64"),
        (("Greeting", "off"), "cd eb d7 02 48 01"),
        (("--hex", "6d06"), "cd eb d7 02 6d 06"),
    ],
)
def test_send(args: tuple[str, ...], wire: str) -> None:
    result = invoke("--json", "send", *args)
    assert result.exit_code == 0, result.output
    assert json.loads(result.stdout)["bytes"] == wire


@pytest.mark.parametrize(
    "args",
    [("Foo",), ("Goto",), ("Goto", "x"), ("Goto", "300"), ("--hex", "zz"), ("--hex", "cdebd7"), ()],
)
def test_send_rejects_bad_commands(args: tuple[str, ...]) -> None:
    result = invoke("send", *args)
    assert result.exit_code == ExitCode.USAGE, result.output
    assert "Traceback" not in result.output


def test_record_then_decode(tmp_path: Path) -> None:
    capture = tmp_path / "capture.glc"
    recorded = invoke("record", str(capture), "--duration", "0.3", real_clock=True)
    assert recorded.exit_code == 0, recorded.output
    assert capture.read_bytes().startswith(b"GALILEO-CAPTURE 1\n")
    decoded = invoke("--json", "decode", str(capture))
    assert decoded.exit_code == 0, decoded.output
    lines = json_lines(decoded.stdout)
    summary = lines[-1]["summary"]
    statuses = lines[:-1]
    assert isinstance(summary, dict)
    assert summary["format"] == "recording"
    assert summary["layout"] == "v2"
    assert summary["frames"] == len(statuses) > 5
    assert summary["bytes_discarded"] == 0
    assert summary["lost_frames"] == 0
    assert all("t" in line and "nav_status" in line for line in statuses)
    stamps = [line["time_stamp"] for line in statuses]
    assert stamps == sorted(stamps)


def test_record_reports_chunks_dropped_when_the_writer_falls_behind(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    @contextlib.asynccontextmanager
    async def burst(url: str, chunks: connectors.ChunkQueue) -> AsyncIterator[float]:
        for index in range(5):  # all at once, before the writer reads one
            chunks.put(float(index), b"\xcd" * 10)
        chunks.end()
        yield 0.0

    monkeypatch.setattr(connectors, "RECORD_QUEUE_CHUNKS", 2)
    monkeypatch.setattr(connectors, "open_raw", burst)
    capture = tmp_path / "burst.bin"
    result = invoke("record", str(capture), "--raw", "--duration", "5", real_clock=True)
    assert capture.read_bytes() == b"\xcd" * 20
    assert "recorded 20 bytes in 2 chunks" in result.stdout
    assert "error: the file writer fell behind: dropped 3 chunks (30 bytes)" in result.stderr
    # This source also ended before the duration: that is the code it exits with.
    assert "error: the link closed" in result.stderr
    assert result.exit_code == ExitCode.CONNECTION, result.output


def test_record_refuses_a_ros_url_before_opening_anything(tmp_path: Path) -> None:
    # The one scheme table of the library (galileo_async.links) serves the CLI too.
    capture = tmp_path / "capture.bin"
    result = invoke("record", str(capture), port="ros://127.0.0.1:9")
    assert result.exit_code == ExitCode.USAGE, result.output
    assert "not a byte stream" in result.stderr
    assert not capture.exists()


def test_record_raw_and_decode_from_stdin(tmp_path: Path) -> None:
    capture = tmp_path / "capture.bin"
    recorded = invoke("record", str(capture), "--raw", "--duration", "0.2", real_clock=True)
    assert recorded.exit_code == 0
    data = capture.read_bytes()
    assert data.startswith(b"\xcd\xeb\xd7")
    decoded = invoke("decode", "-", "--summary-only", input=data)
    assert decoded.exit_code == 0, decoded.output
    assert decoded.stdout == ""
    assert "format raw" in decoded.stderr
    assert "layout v2" in decoded.stderr


def test_decode_counts_garbage_and_lost_frames(tmp_path: Path) -> None:
    capture = tmp_path / "faulty.glc"
    port = "sim://?speed=20&garbage=0.3&drop=0.2&layout=v1&seed=3"
    recorded = invoke("record", str(capture), "--duration", "0.3", port=port, real_clock=True)
    assert recorded.exit_code == 0
    decoded = invoke("decode", str(capture), "--json")
    summary = json_lines(decoded.stdout)[-1]["summary"]
    assert isinstance(summary, dict)
    assert summary["layout"] == "v1"
    assert summary["bytes_discarded"] > 0
    assert summary["resyncs"] > 0
    assert summary["lost_frames"] > 0


def test_decode_missing_file_and_garbage(tmp_path: Path) -> None:
    missing = invoke("decode", str(tmp_path / "nope"))
    assert missing.exit_code == ExitCode.ERROR
    assert "cannot read" in missing.stderr
    junk = tmp_path / "junk"
    junk.write_bytes(bytes(range(256)) * 4)
    result = invoke("decode", str(junk))
    assert result.exit_code == ExitCode.ERROR  # bytes but not one frame
    assert "frames 0" in result.stderr


def test_ports_json() -> None:
    result = invoke("ports", "--json")
    assert result.exit_code == 0
    ports = json.loads(result.stdout)
    assert isinstance(ports, list)
    assert all({"device", "description", "hwid"} <= set(port) for port in ports)


def test_demo_runs_the_tour() -> None:
    result = invoke("demo", "--speed", "20", port=None)
    assert result.exit_code == 0, result.output
    for step in ("start navigation", "go to target 0", "pause and resume", "the point",
                 "not on the map", "patrol", "stop navigation"):  # fmt: skip
        assert step in result.stdout
    assert "✘" not in result.stdout
    assert result.stdout.count("✔") == 7


def test_demo_refuses_a_real_robot() -> None:
    result = invoke("demo", port="/dev/ttyUSB0")
    assert result.exit_code == ExitCode.USAGE


def test_teleop_needs_a_terminal() -> None:
    result = invoke("teleop")
    assert result.exit_code == ExitCode.ERROR
    assert "tty" in result.stderr


def test_help_names_every_url_form() -> None:
    result = invoke("--help", port=None)
    assert result.exit_code == 0
    text = " ".join(word for word in result.stdout.split() if word != "│")  # rich's box
    for form in ("socket://host:port", "ros://host[:port]", "sim://", "--map-targets"):
        assert form in text


def test_version() -> None:
    result = invoke("--version", port=None)
    assert result.exit_code == 0
    assert result.stdout.startswith("galileo ")


@pytest.mark.parametrize(
    ("port", "args", "message"),
    [
        ("sim://?bogus=1", ("status",), "unknown simulator option"),
        ("sim://?speed=abc", ("demo",), "bad value for simulator option speed"),
        ("socket://nohost", ("status",), "expected socket://host:port"),
        (FAST, ("sim", "--tcp", "nonsense"), "HOST:PORT"),
    ],
)
def test_bad_urls_are_usage_errors(port: str, args: tuple[str, ...], message: str) -> None:
    result = invoke(*args, port=port)
    assert result.exit_code == ExitCode.USAGE
    assert message in result.stderr
