"""Pure pieces of the CLI: key parsing, raw command parsing, capture files, exit codes."""

from __future__ import annotations

import io
import struct

import anyio
import pytest
import typer
from hypothesis import given
from hypothesis import strategies as st

from galileo_async.cli.capture import MAGIC, RECORD, iter_capture
from galileo_async.cli.connectors import RECORD_QUEUE_CHUNKS, ChunkQueue
from galileo_async.cli.ops import parse_command
from galileo_async.cli.render import event_text, goal_line, link_dict, status_dict, status_line
from galileo_async.cli.runner import (
    ExitCode,
    Settings,
    exit_code_for,
    fail,
    report,
    run,
    with_query,
)
from galileo_async.cli.teleop import KEYS, parse_keys
from galileo_async.errors import (
    AcceptTimeout,
    ConnectionLost,
    GalileoError,
    GoalAborted,
    GoalCancelled,
    GoalRejected,
    GoalStalled,
    InvalidArgument,
    LinkStale,
    NotReady,
    OperationTimeout,
)
from galileo_async.events import GoalReached, NavigationOpened
from galileo_async.models import GalileoStatus, StatusLayout, TargetStatus
from galileo_async.protocol import AddTarget, Goto, Greeting, RawCommand, Stop, TurnLeft
from galileo_async.transports import LinkStats


@pytest.mark.parametrize(
    ("data", "actions", "rest"),
    [
        (b"w", ["forward"], b""),
        (b"WASD", ["forward", "left", "backward", "right"], b""),
        (b"\x1b[A\x1b[B\x1b[C\x1b[D", ["forward", "backward", "right", "left"], b""),
        (b"\x1bOA", ["forward"], b""),
        (b" +-q", ["stop", "faster", "slower", "quit"], b""),
        (b"w\x1b", ["forward"], b"\x1b"),
        (b"w\x1b[", ["forward"], b"\x1b["),
        (b"\x1b[Zw", ["forward"], b""),  # an unused sequence is skipped
        (b"xyz\x00", [], b""),
        (b"\x03", ["quit"], b""),
    ],
)
def test_parse_keys(data: bytes, actions: list[str], rest: bytes) -> None:
    assert parse_keys(data) == (actions, rest)


@given(st.lists(st.sampled_from(sorted(KEYS)), max_size=20), st.data())
def test_parse_keys_is_split_invariant(keys: list[bytes], data: st.DataObject) -> None:
    stream = b"".join(keys)
    cut = data.draw(st.integers(0, len(stream)))
    first, pending = parse_keys(stream[:cut])
    second, rest = parse_keys(pending + stream[cut:])
    assert first + second == [KEYS[key] for key in keys]
    assert rest == b""


@pytest.mark.parametrize(
    ("name", "args", "expected"),
    [
        ("Goto", ["3"], Goto(3)),
        ("goto", ["0x10"], Goto(16)),
        ("turn_left", ["40"], TurnLeft(40)),
        ("Stop", [], Stop()),
        ("stop", ["5"], Stop(5)),
        ("AddTarget", ["1.5", "-2"], AddTarget(1.5, -2.0)),
        ("Greeting", ["on"], Greeting(True)),
        ("RawCommand", ["6d05"], RawCommand(b"m\x05")),
    ],
)
def test_parse_command(name: str, args: list[str], expected: object) -> None:
    assert parse_command(name, args) == expected


@pytest.mark.parametrize(
    ("name", "args", "message"),
    [
        ("Nope", [], "unknown command"),
        ("Goto", [], "TARGET_ID"),
        ("Goto", ["1", "2"], "TARGET_ID"),
        ("Goto", ["one"], "must be int"),
        ("Goto", ["256"], "0..255"),
        ("Greeting", ["maybe"], "true or false"),
        ("AddTarget", ["nan", "0"], "finite"),
    ],
)
def test_parse_command_errors(name: str, args: list[str], message: str) -> None:
    with pytest.raises(InvalidArgument, match=message):
        parse_command(name, args)


def _recording(*chunks: tuple[float, bytes]) -> bytes:
    return MAGIC + b"".join(RECORD.pack(t, len(data)) + data for t, data in chunks)


def test_iter_capture_reads_a_recording() -> None:
    data = _recording((0.0, b"abc"), (0.5, b"defg"))
    assert list(iter_capture(io.BytesIO(data))) == [(0.0, b"abc"), (0.5, b"defg")]


def test_iter_capture_stops_at_a_cut_off_record() -> None:
    data = _recording((0.0, b"abc"), (0.5, b"defg"))
    assert list(iter_capture(io.BytesIO(data[:-2]))) == [(0.0, b"abc"), (0.5, b"de")]
    cut_header = data[: len(MAGIC) + RECORD.size + 3 + 5]
    assert list(iter_capture(io.BytesIO(cut_header))) == [(0.0, b"abc")]


def test_iter_capture_reads_raw_bytes_and_short_files() -> None:
    assert list(iter_capture(io.BytesIO(b"\xcd\xeb\xd7" * 10))) == [
        (None, b"\xcd\xeb\xd7" * 6),
        (None, b"\xcd\xeb\xd7" * 4),
    ]
    assert list(iter_capture(io.BytesIO(b"GAL"))) == [(None, b"GAL")]
    assert list(iter_capture(io.BytesIO(b""))) == []


def test_record_header_layout_is_documented() -> None:
    assert RECORD.size == 12
    assert RECORD.pack(1.0, 2) == struct.pack("<d", 1.0) + (2).to_bytes(4, "little")


@pytest.mark.parametrize(
    ("exc", "code"),
    [
        (GoalRejected("x", target_id=1), ExitCode.REJECTED),
        (GoalAborted("x", target_id=1, distance=2.0), ExitCode.ABORTED),
        (GoalStalled("x", target_id=1, stalled_for=60.0), ExitCode.ABORTED),
        (GoalCancelled("x", target_id=1, preempted=True), ExitCode.CANCELLED),
        (AcceptTimeout("x", target_id=1), ExitCode.TIMEOUT),
        (OperationTimeout("x"), ExitCode.TIMEOUT),
        (ConnectionLost("x"), ExitCode.CONNECTION),
        (LinkStale("x", silent_for=2.0), ExitCode.CONNECTION),
        (NotReady("x", None), ExitCode.NOT_READY),
        (InvalidArgument("x"), ExitCode.USAGE),
        (GalileoError("x"), ExitCode.ERROR),
        (OSError("x"), ExitCode.ERROR),
    ],
)
def test_exit_codes(exc: BaseException, code: ExitCode) -> None:
    assert exit_code_for(exc) is code


def test_exit_codes_are_distinct() -> None:
    assert len({int(code) for code in ExitCode}) == len(ExitCode)


def test_sim_url_gets_the_global_layout() -> None:
    assert Settings(port="sim://", layout="v1").url == "sim://?layout=v1"
    assert Settings(port="sim://?layout=v2&speed=3", layout="v1").url == (
        "sim://?layout=v2&speed=3"
    )
    assert Settings(port="/dev/ttyUSB0", layout="v1").url == "/dev/ttyUSB0"
    assert with_query("sim://?speed=2", speed="5", seed="1") == "sim://?speed=2&seed=1"


def test_connect_options() -> None:
    assert Settings(port="sim://?targets=1,2;3,4").connect_options() == {"map_targets": 2}
    assert Settings(port="sim://", map_targets=9).connect_options() == {"map_targets": 9}
    serial = Settings(port="/dev/ttyUSB0", layout="v1").connect_options()
    assert serial == {"layout": "v1", "reconnect": False, "control_socket": True}
    udp = Settings(port="udp://10.0.0.5", extra={"control_socket": False}).connect_options()
    assert udp == {"reconnect": False, "control_socket": False}  # a profile may turn it off
    assert "control_socket" not in Settings(port="socket://10.0.0.5:4001").connect_options()


@pytest.mark.parametrize("layout", [StatusLayout.UDP_V1, StatusLayout.UDP_V2])
def test_a_speed_the_link_does_not_carry_shows_as_unknown(layout: StatusLayout) -> None:
    # udp:// frames have no speed fields (None): never "0.00 m/s" while the robot moves.
    status = GalileoStatus(
        layout=layout, nav_status=1, visual_status=1, target_num_id=2,
        target_status=TargetStatus.WORKING, target_distance=1.25, current_pose_x=1.0,
        current_pose_y=-2.0, current_angle=0.0,
    )  # fmt: skip
    assert status.current_speed_x is None
    assert status_line(status).endswith(" · speed n/a")
    assert goal_line(status) == "target 2 working · 1.25 m to go · speed n/a"
    for line in (status_line(status), goal_line(status)):
        assert "m/s" not in line


def test_render_status_and_events() -> None:
    status = GalileoStatus(
        nav_status=1, visual_status=1, target_num_id=2, target_status=TargetStatus.WORKING,
        target_distance=1.25, current_pose_x=1.0, current_pose_y=-2.0, current_angle=0.0,
        current_speed_x=0.5,
    )  # fmt: skip
    line = status_line(status)
    assert "nav open" in line
    assert "target 2 working 1.25 m" in line
    assert "(+1.000, -2.000) +0.0°" in line
    assert "+0.50 m/s" in line
    assert status_dict(status)["target_status"] == 1
    assert goal_line(status) == "target 2 working · 1.25 m to go · 0.50 m/s"
    assert event_text(GoalReached(status=status, target_id=2, distance=0.004)) == (
        "GoalReached target_id=2 distance=0.00"
    )
    assert event_text(NavigationOpened(status=None)) == "NavigationOpened"


def test_link_dict_is_json_ready() -> None:
    stats = LinkStats(frames=3, layout=StatusLayout.V1)
    values = link_dict(stats)
    assert values["frames"] == 3
    assert values["layout"] == "v1"
    assert values["last_frame_age"] is None
    assert "last_frame_at" not in values


def test_errors_inside_task_groups_are_reported_as_one_line(
    capsys: pytest.CaptureFixture[str],
) -> None:
    async def main() -> int:
        async def fail() -> None:
            raise ConnectionLost("the link dropped")

        async with anyio.create_task_group() as group:
            group.start_soon(fail)
        return 0

    with pytest.raises(typer.Exit) as exit_info:
        run(Settings(), main)
    assert exit_info.value.exit_code == ExitCode.CONNECTION
    assert capsys.readouterr().err.strip() == "error: ConnectionLost: the link dropped"


def test_a_bug_is_one_line_too(capsys: pytest.CaptureFixture[str]) -> None:
    async def main() -> int:
        raise KeyError("bug")

    with pytest.raises(typer.Exit) as exited:
        run(Settings(), main)
    assert exited.value.exit_code == ExitCode.ERROR
    assert capsys.readouterr().err.strip() == "error: KeyError: 'bug' (a bug: -v shows where)"


def test_markup_in_messages_is_printed_as_is(capsys: pytest.CaptureFixture[str]) -> None:
    report(GalileoError("cannot open [Errno 2] [bold]x[/bold]"), verbose=0)
    expected = "error: GalileoError: cannot open [Errno 2] [bold]x[/bold]"
    assert capsys.readouterr().err.strip() == expected


def test_every_error_line_has_one_format(capsys: pytest.CaptureFixture[str]) -> None:
    report(NotReady("goto: navigation must be open", None), verbose=0)
    report(OSError("port busy"), verbose=0)
    with pytest.raises(typer.Exit):
        fail("bad input", ExitCode.USAGE)
    lines = capsys.readouterr().err.splitlines()
    assert lines[0].startswith("error: NotReady: goto: navigation must be open (start it with")
    assert lines[1:] == ["error: OSError: port busy", "error: bad input"]


async def test_chunk_queue_is_bounded_and_counts_what_it_drops() -> None:
    assert RECORD_QUEUE_CHUNKS >= 1024
    chunks = ChunkQueue(limit=2)
    for index in range(5):
        chunks.put(float(index), bytes([index]) * (index + 1))
    chunks.end()  # the queue is full: the end still shows once it is drained
    with anyio.fail_after(5):
        got = [await chunks.get() for _ in range(3)]
    assert got == [(0.0, b"\x00"), (1.0, b"\x01\x01"), None]
    assert (chunks.dropped_chunks, chunks.dropped_bytes) == (3, 3 + 4 + 5)


async def test_chunk_queue_end_wakes_a_waiting_reader() -> None:
    chunks = ChunkQueue(limit=2)
    got: list[object] = []
    with anyio.fail_after(5):
        async with anyio.create_task_group() as group:

            async def read() -> None:
                got.append(await chunks.get())

            group.start_soon(read)
            await anyio.wait_all_tasks_blocked()
            chunks.end()
    assert got == [None]
    assert chunks.dropped_chunks == 0
