"""Device side: CommandDecoder (the firmware parser, docs/protocol.md §2) and encode_status."""

from __future__ import annotations

import dataclasses
import itertools
import struct

import pytest
from hypothesis import assume, given
from hypothesis import strategies as st

from galileo_async.models import GalileoStatus, StatusLayout
from galileo_async.protocol import (
    COMMAND_TYPES,
    HEADER,
    LAYOUTS,
    MAX_COMMAND_PAYLOAD,
    MAX_COORDINATE,
    AddTarget,
    Command,
    CommandDecoder,
    Forward,
    Goto,
    Greeting,
    RawCommand,
    RotateTo,
    SetPatrolDwell,
    StartNavigation,
    StatusDecoder,
    StatusEncoder,
    Stop,
    StopNavigation,
    encode,
    encode_status,
    nudge_coordinates,
    parse_payload,
)
from tests.support import vectors as v
from tests.support.vectors import (
    ALL_LAYOUTS,
    FIELDS_OF,
    V1,
    V2,
    V2T,
    next_header,
    statuses,
    unambiguous,
)

GOLDEN = [(command, v.command_frame(hex_frame)) for command, hex_frame in v.COMMAND_VECTORS]


@pytest.mark.parametrize(("command", "frame"), GOLDEN, ids=[repr(c) for c, _ in GOLDEN])
def test_golden_frame_decodes_to_the_command(command: Command, frame: bytes) -> None:
    decoder = CommandDecoder()
    assert decoder.feed(frame) == [command]
    decoder = CommandDecoder()
    assert [c for i in range(len(frame)) for c in decoder.feed(frame[i : i + 1])] == [command]
    assert decoder.stats.commands == 1
    assert (decoder.stats.aborted, decoder.stats.bad_lengths) == (0, 0)


def test_all_golden_frames_in_one_stream() -> None:
    decoder = CommandDecoder()
    stream = b"\x00garbage" + b"".join(frame for _, frame in GOLDEN)
    assert decoder.feed(stream) == [command for command, _ in GOLDEN]
    for cut in range(len(stream)):
        decoder = CommandDecoder()
        assert decoder.feed(stream[:cut]) + decoder.feed(stream[cut:]) == [c for c, _ in GOLDEN]


def test_header_inside_a_payload_aborts_the_command() -> None:
    decoder = CommandDecoder()
    # 'g' 'i' announced 10 bytes; a header after 5 of them starts over.
    out = decoder.feed(HEADER + b"\x0agi\x00\x00\x80" + encode(StartNavigation()))
    assert out == [StartNavigation()]
    assert decoder.stats.aborted == 1


def test_partial_command_is_dropped_at_the_next_header() -> None:
    decoder = CommandDecoder()
    assert decoder.feed(HEADER + b"\x05m\x00") == []
    assert decoder.feed(encode(Goto(7))) == [Goto(7)]
    assert decoder.stats.aborted == 1
    assert decoder.stats.commands == 1


@pytest.mark.parametrize("length", [0, MAX_COMMAND_PAYLOAD + 1, 0x55, 0xFF])
def test_bad_length_is_ignored_until_the_next_header(length: int) -> None:
    decoder = CommandDecoder()
    junk = HEADER + bytes((length,)) + b"\x02m\x00" * 10
    assert decoder.feed(junk + encode(StopNavigation())) == [StopNavigation()]
    assert decoder.stats.bad_lengths == 1
    assert decoder.stats.aborted == 0


def test_longest_payload_is_accepted() -> None:
    payload = bytes(range(1, MAX_COMMAND_PAYLOAD + 1))
    assert CommandDecoder().feed(HEADER + bytes((MAX_COMMAND_PAYLOAD,)) + payload) == [
        RawCommand(payload)
    ]


def test_bytes_outside_frames_are_ignored() -> None:
    decoder = CommandDecoder()
    assert decoder.feed(b"\x02m\x00\xcd\xeb\x00\xd7") == []
    assert decoder.feed(b"\xcd" + encode(Goto(1))) == [Goto(1)]
    assert (decoder.stats.aborted, decoder.stats.bad_lengths) == (0, 0)


def test_header_float_yields_the_measured_spurious_command() -> None:
    # docs/protocol.md §2: 'g' 'i' whose float bytes are "cd eb d7 02" aborts, the 02 becomes a
    # length byte, and the next write's "cd eb" completes a 2-byte command.
    decoder = CommandDecoder()
    assert decoder.feed(HEADER + b"\x0agi" + b"\x00\x00\xc0\x3f" + HEADER + b"\x02") == []
    assert decoder.stats.aborted == 1
    assert decoder.feed(encode(StartNavigation())) == [RawCommand(b"\xcd\xeb"), StartNavigation()]


def test_back_to_back_commands_all_parse() -> None:
    commands = [Goto(i) for i in range(50)]
    assert CommandDecoder().feed(b"".join(map(encode, commands))) == commands


@pytest.mark.parametrize(
    ("payload", "command"),
    [
        (b"g\x05", Goto(5)),
        (b"a\x01\x00", RotateTo(0)),
        (b"a\x00\xb4", RotateTo(180)),
        (b"m\x05\x00", SetPatrolDwell(0)),
        (b"H\x00", Greeting(True)),
        (b"H\x01", Greeting(False)),
        (b"s\x32", Stop(50)),
        (b"f\x64", Forward(100)),
        (b"gi" + struct.pack("<ff", -3.5, 0.125), AddTarget(-3.5, 0.125)),
        (b"gi" + struct.pack("<ff", 1e-3, 0.0), AddTarget(0.0010000000474974513, 0.0)),
    ],
)  # fmt: skip
def test_parse_payload(payload: bytes, command: Command) -> None:
    assert parse_payload(payload) == command


@pytest.mark.parametrize(
    "payload",
    [
        b"f\x65",  # 101 %
        b"s\xff",
        b"a\x02\x0a",  # sign byte neither 0 nor 1
        b"a\x00\xb5",  # 181 degrees
        b"H\x02",
        b"m\x01",
        b"m\x05\x01\x02",
        b"gr\x01",
        b"g",
        b"g\x01\x02",
        b"gi" + struct.pack("<ff", float("nan"), 0.0),
        b"gi" + struct.pack("<ff", 0.0, MAX_COORDINATE * 2),
        b"gi\x00\x00",
        b"\xaa\x45",
        b"V\x04",
        b"j\x03",
        b"\x00",
    ],
)
def test_unknown_or_out_of_range_payload_is_a_raw_command(payload: bytes) -> None:
    assert parse_payload(payload) == RawCommand(payload)
    assert CommandDecoder().feed(HEADER + bytes((len(payload),)) + payload) == [RawCommand(payload)]


# --- encode_status: the robot's side of the status stream (docs/protocol.md §1) ----------------


def test_protocol_example_frame_is_the_firmware_defaults() -> None:
    assert len(v.V2_EXAMPLE) == 89
    assert v.V2_EXAMPLE[3] == 0x55
    status = GalileoStatus(layout=V2, time_stamp=1)  # every other field: firmware default
    assert encode_status(status) == v.V2_EXAMPLE
    assert StatusDecoder().feed(v.V2_EXAMPLE) == [v.V2_EXAMPLE_STATUS]
    assert v.V2_EXAMPLE_STATUS.pose is not None  # zeros are a pose; -1 would be unknown


@pytest.mark.parametrize(("name", "frame", "status"), v.STATUS_VECTORS)
def test_encode_status_matches_golden(name: str, frame: bytes, status: GalileoStatus) -> None:
    assert encode_status(status) == frame
    assert len(frame) == LAYOUTS[status.layout].frame_size


def test_encode_status_in_another_layout() -> None:
    assert encode_status(v.V2_ACTIVE_STATUS, "v2_truncated") == v.V2_ACTIVE[:53]
    assert encode_status(v.V2_ACTIVE_STATUS.model_copy(update={"layout": StatusLayout.ROS})) == (
        v.V2_ACTIVE
    )
    v1_payload = struct.pack(v.V1_FORMAT, 1, 2, 24.5, 7, 1, 3.25, 0, 0.5, -0.25, 0.375, -0.125, 5)
    assert encode_status(v.V2_ACTIVE_STATUS, V1) == HEADER + b"\x31" + v1_payload + b"\x00"
    # Fields the status lacks are sent as the firmware defaults.
    assert encode_status(v.V1_STATUS, V2)[4:] == struct.pack(
        v.V2_FORMAT, 1, 1, 0, 0, 0, 0, 0, 12.5, 4, 0, 0.004999999888241291, 1, 0.25, -0.5,
        0.125, 0.0625, 77, 0.0, 0.0, 0.0, 0,
    ) + b"\x00"  # fmt: skip


@pytest.mark.parametrize("layout", ALL_LAYOUTS)
def test_status_encoder_takes_values_in_any_order(layout: StatusLayout) -> None:
    status = v.V2_ACTIVE_STATUS
    fields = ("power", "target_status", "nav_status", "current_pose_x")  # most left out
    encoder = StatusEncoder(layout, fields)
    values = tuple(getattr(status, name) for name in fields)
    # A field left out goes out as the firmware default, like a field the status lacks.
    expected = GalileoStatus(layout=layout, **{name: getattr(status, name) for name in fields})
    assert encoder.frame(values) == encode_status(expected)
    assert encoder.encode(values) == encode_status(expected)
    stamped = encode_status(expected.model_copy(update={"time_stamp": 9}))
    assert encoder.encode(values, time_stamp=9) == stamped
    assert encoder.encode(values, time_stamp=9) == stamped  # the cached frame, stamped again


@given(st.tuples(st.sampled_from(ALL_LAYOUTS), statuses(V2)))
def test_round_trip_pinned(case: tuple[StatusLayout, GalileoStatus]) -> None:
    layout, full = case
    frame = encode_status(full, layout)
    assert len(frame) == LAYOUTS[layout].frame_size
    out = StatusDecoder(layout).feed(frame + next_header(layout))
    # A layout loses the fields it does not carry, by design; the rest are exact.
    kept = {name: getattr(full, name) for name in FIELDS_OF[layout]}
    assert out == [GalileoStatus(layout=layout, **kept)]


@given(st.sampled_from(ALL_LAYOUTS).flatmap(unambiguous))
def test_round_trip_auto_detected(status: GalileoStatus) -> None:
    frame = encode_status(status)
    assume(HEADER not in frame[1:])
    copies = 2 if status.layout is V2T else 1  # one alone could still be the start of a v2
    decoder = StatusDecoder()
    assert decoder.feed(frame * copies + next_header(status.layout)) == [status] * copies
    assert decoder.layout is status.layout


# --- hypothesis: commands --------------------------------------------------------------

COORDINATE = st.floats(-MAX_COORDINATE, MAX_COORDINATE, width=32)
PERCENT = st.integers(0, 100)
STRATEGIES: dict[str, st.SearchStrategy[Command]] = {
    name: st.just(cls()) for name, cls in COMMAND_TYPES.items() if not dataclasses.fields(cls)
}
STRATEGIES |= {
    "Goto": st.builds(Goto, st.integers(0, 255)),
    "AddTarget": st.builds(AddTarget, COORDINATE, COORDINATE),
    "Forward": st.builds(COMMAND_TYPES["Forward"], PERCENT),
    "Backward": st.builds(COMMAND_TYPES["Backward"], PERCENT),
    "TurnLeft": st.builds(COMMAND_TYPES["TurnLeft"], PERCENT),
    "TurnRight": st.builds(COMMAND_TYPES["TurnRight"], PERCENT),
    "Stop": st.builds(Stop, PERCENT),
    "RotateTo": st.builds(RotateTo, st.integers(-180, 180)),
    "SetPatrolDwell": st.builds(SetPatrolDwell, st.integers(0, 255)),
    "Greeting": st.builds(Greeting, st.booleans()),
    "RawCommand": st.binary(min_size=1, max_size=MAX_COMMAND_PAYLOAD)
    .filter(lambda b: HEADER not in b)
    .map(RawCommand),
}
COMMANDS = st.one_of(*STRATEGIES.values())


def test_every_command_type_has_a_strategy() -> None:
    assert set(STRATEGIES) == set(COMMAND_TYPES)


def expected_after_the_wire(command: Command) -> Command:
    """What the robot sees: nudged coordinates, and known payloads under their own type."""
    if isinstance(command, AddTarget):
        return AddTarget(*nudge_coordinates(command.x, command.y))
    if isinstance(command, RawCommand):
        return parse_payload(command.data)
    return command


@given(st.lists(COMMANDS, min_size=1, max_size=8), st.data())
def test_round_trip_through_the_device_parser(commands: list[Command], data: st.DataObject) -> None:
    stream = b"".join(encode(c) for c in commands)
    cuts = sorted(data.draw(st.lists(st.integers(0, len(stream)), max_size=6)))
    edges = [0, *cuts, len(stream)]
    decoder = CommandDecoder()
    out = [c for a, b in itertools.pairwise(edges) for c in decoder.feed(stream[a:b])]
    assert out == [expected_after_the_wire(c) for c in commands]
    assert (decoder.stats.aborted, decoder.stats.bad_lengths) == (0, 0)


@given(COMMANDS)
def test_known_commands_round_trip_to_an_equal_object(command: Command) -> None:
    if not isinstance(command, (AddTarget, RawCommand)):
        assert CommandDecoder().feed(encode(command)) == [command]


@given(st.binary(max_size=500), st.integers(1, 64))
def test_random_bytes_never_raise(data: bytes, chunk: int) -> None:
    decoder = CommandDecoder()
    out = [c for i in range(0, len(data), chunk) for c in decoder.feed(data[i : i + chunk])]
    assert decoder.stats.commands == len(out)
    for command in out:
        assert 1 <= len(command.payload()) <= MAX_COMMAND_PAYLOAD
