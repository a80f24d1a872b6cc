"""Command objects: golden frames of docs/protocol.md §2, validation, the header nudge."""

from __future__ import annotations

import dataclasses
import math
import struct

import pytest
from hypothesis import given
from hypothesis import strategies as st

from galileo_async.errors import GalileoError, InvalidArgument
from galileo_async.protocol import (
    COMMAND_TYPES,
    HEADER,
    MAX_COMMAND_PAYLOAD,
    MAX_COORDINATE,
    AddTarget,
    Backward,
    Command,
    Forward,
    Goto,
    Greeting,
    RawCommand,
    RotateTo,
    SetPatrolDwell,
    StartNavigation,
    Stop,
    StopPatrol,
    TurnLeft,
    TurnRight,
    encode,
    nudge_coordinates,
)
from tests.support import vectors as v

F32 = struct.Struct("<f")
U32 = struct.Struct("<I")


def f32_bits(value: float) -> int:
    return int(U32.unpack(F32.pack(value))[0])


def from_bits(bits: int) -> float:
    return float(F32.unpack(U32.pack(bits))[0])


@pytest.mark.parametrize(
    ("command", "hex_frame"), v.COMMAND_VECTORS, ids=[repr(c) for c, _ in v.COMMAND_VECTORS]
)
def test_golden_frame(command: Command, hex_frame: str) -> None:
    frame = v.command_frame(hex_frame)
    assert encode(command) == frame
    assert frame[:3] == HEADER
    assert frame[3] == len(frame) - 4 == len(command.payload())
    assert 1 <= frame[3] <= MAX_COMMAND_PAYLOAD
    assert HEADER not in frame[1:]


def test_every_command_type_has_a_golden_vector() -> None:
    covered = {type(command) for command, _ in v.COMMAND_VECTORS}
    assert covered == set(COMMAND_TYPES.values())
    assert len(COMMAND_TYPES) == 27
    for name, cls in COMMAND_TYPES.items():
        assert cls.__name__ == name == cls.name


def test_stop_patrol_is_the_firmware_m6_not_the_documented_m4() -> None:
    # docs/protocol.md §2.g: 'm' 4 stops the whole navigation service.
    assert StopPatrol().payload() == b"m\x06"


def test_mapping_uses_uppercase_v() -> None:
    assert {COMMAND_TYPES[n]().payload()[0] for n in ("StartMapping", "SaveMap")} == {0x56}


@pytest.mark.parametrize(
    "make",
    [
        lambda: Goto(-1),
        lambda: Goto(256),
        lambda: Goto(True),
        lambda: Goto(3.0),
        lambda: Goto("3"),
        lambda: Goto(None),
        lambda: Forward(101),
        lambda: Backward(-1),
        lambda: TurnLeft(False),
        lambda: TurnRight(50.5),
        lambda: Stop(101),
        lambda: Stop(-1),
        lambda: Stop(True),
        lambda: RotateTo(181),
        lambda: RotateTo(-181),
        lambda: RotateTo(90.0),
        lambda: RotateTo(True),
        lambda: SetPatrolDwell(256),
        lambda: SetPatrolDwell(-1),
        lambda: SetPatrolDwell(True),
        lambda: SetPatrolDwell(1.5),
        lambda: Greeting(1),
        lambda: Greeting("on"),
        lambda: AddTarget(math.nan, 0.0),
        lambda: AddTarget(0.0, math.inf),
        lambda: AddTarget(-math.inf, 0.0),
        lambda: AddTarget(MAX_COORDINATE * 1.0001, 0.0),
        lambda: AddTarget(0.0, -MAX_COORDINATE - 1),
        lambda: AddTarget(True, 0.0),
        lambda: AddTarget(0.0, False),
        lambda: AddTarget("1.0", 0.0),
        lambda: AddTarget(None, 0.0),
        lambda: RawCommand(b""),
        lambda: RawCommand(bytes(MAX_COMMAND_PAYLOAD + 1)),
        lambda: RawCommand("m0"),
        lambda: RawCommand([0x6D, 0]),
        lambda: RawCommand(b"x" + HEADER),
        lambda: RawCommand(HEADER),
    ],
)
def test_invalid_arguments_raise_at_construction(make: object) -> None:
    assert callable(make)
    with pytest.raises(InvalidArgument) as raised:
        make()
    assert isinstance(raised.value, ValueError)
    assert isinstance(raised.value, GalileoError)


@pytest.mark.parametrize(
    "command",
    [
        Goto(0), Goto(255), Forward(0), Forward(100), TurnRight(100), Stop(0), Stop(100),
        RotateTo(-180), RotateTo(180), RotateTo(0), SetPatrolDwell(0), SetPatrolDwell(255),
        AddTarget(MAX_COORDINATE, -MAX_COORDINATE), AddTarget(1, -2), AddTarget(-0.0, 1e-45),
        RawCommand(bytes(MAX_COMMAND_PAYLOAD)), RawCommand(bytearray(b"\xcd\xeb")),
        RawCommand(b"\xeb\xd7\xcd"),
    ],
)  # fmt: skip
def test_boundary_values_are_accepted(command: Command) -> None:
    frame = encode(command)
    assert frame[3] == len(command.payload())
    assert HEADER not in frame[1:]


def test_commands_are_frozen_hashable_values() -> None:
    goto = Goto(3)
    with pytest.raises(dataclasses.FrozenInstanceError):
        goto.target_id = 4  # type: ignore[misc]
    assert goto == Goto(3)
    assert goto != Goto(4)
    assert StartNavigation() != StopPatrol()
    assert len({Goto(3), Goto(3), AddTarget(1.0, 2.0), AddTarget(1.0, 2.0)}) == 2


def test_raw_command_keeps_bytes() -> None:
    raw = RawCommand(bytearray(b"m\x00"))
    assert type(raw.data) is bytes
    assert encode(raw) == v.command_frame("cdebd7 02 6d 00")


# --- the CD EB D7 nudge (docs/protocol.md §2.d) --------------------------------------------------


def header_floats() -> list[float]:
    """Every float32 within MAX_COORDINATE whose low three bytes are CD EB D7."""
    found = []
    for top in range(256):
        value = from_bits(top << 24 | 0xD7EBCD)
        if math.isfinite(value) and abs(value) <= MAX_COORDINATE:
            found.append(value)
    return found


HEADER_FLOATS = header_floats()


def test_header_floats_exist_in_the_valid_range() -> None:
    assert F32.pack(HEADER_FLOATS[0])[:3] == HEADER
    assert len(HEADER_FLOATS) > 60  # both signs, from tiny to ~27 km
    assert any(1.0 < abs(x) < 2.0 for x in HEADER_FLOATS)  # 1.6869 m is a real position


@pytest.mark.parametrize("value", HEADER_FLOATS, ids=lambda x: f"{x:.4g}")
def test_header_float_is_nudged_by_one_ulp(value: float) -> None:
    for command, index in ((AddTarget(value, 0.5), 0), (AddTarget(-0.5, value), 1)):
        frame = encode(command)
        assert HEADER not in frame[1:]
        sent = struct.unpack_from("<ff", frame, 6)[index]
        assert f32_bits(sent) == f32_bits(value) + 1  # the next float32 away from zero
        assert math.copysign(1.0, sent) == math.copysign(1.0, value)
        assert abs(sent) > abs(value)
        assert abs(sent - value) == ulp32(value)
        other = struct.unpack_from("<ff", frame, 6)[1 - index]
        assert other == (0.5 if index == 0 else -0.5)  # the other coordinate is untouched
    both = encode(AddTarget(value, value))
    assert HEADER not in both[1:]
    assert struct.unpack_from("<ff", both, 6) == (from_bits(f32_bits(value) + 1),) * 2


def ulp32(value: float) -> float:
    """Spacing of float32 values at ``value`` (normal range)."""
    exponent = (f32_bits(value) >> 23) & 0xFF
    return 2.0 ** (max(exponent, 1) - 127 - 23)


def test_nudge_coordinates_leaves_ordinary_values_alone() -> None:
    assert nudge_coordinates(1.5, -2.0) == (1.5, -2.0)
    x, y = nudge_coordinates(0.1, 0.2)
    assert (x, y) == (F32.unpack(F32.pack(0.1))[0], F32.unpack(F32.pack(0.2))[0])


@given(
    st.floats(-MAX_COORDINATE, MAX_COORDINATE, width=32),
    st.floats(-MAX_COORDINATE, MAX_COORDINATE, width=32),
    st.sampled_from([None, *HEADER_FLOATS]),
    st.booleans(),
)
def test_add_target_never_sends_a_header(
    x: float, y: float, forced: float | None, on_x: bool
) -> None:
    if forced is not None:
        x, y = (forced, y) if on_x else (x, forced)
    frame = encode(AddTarget(x, y))
    assert len(frame) == 14
    assert HEADER not in frame[1:]
    sent = struct.unpack_from("<ff", frame, 6)
    for original, value in zip((x, y), sent, strict=True):
        moved = f32_bits(value) - f32_bits(original)
        assert moved == (1 if F32.pack(original)[:3] == HEADER else 0)
