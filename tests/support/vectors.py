"""Golden wire vectors written out from docs/protocol.md, independent of the encoders under test.

Also the hypothesis strategies that generate statuses exactly representable on the wire.

Command frames are hex strings copied from the docs/protocol.md §2 table. Status frames are
packed here with ``struct`` straight from the docs/protocol.md §1 tables (field order and
types spelled out again below, not taken from ``galileo_async.protocol.layouts``), except
the §1 example frame, which is the document's hex verbatim.
"""

from __future__ import annotations

import struct

from hypothesis import strategies as st

from galileo_async.models import GalileoStatus, StatusLayout
from galileo_async.protocol import (
    AddTarget,
    Backward,
    Cancel,
    Command,
    Forward,
    Goto,
    Greeting,
    Pause,
    RawCommand,
    ResetTargets,
    Resume,
    RotateTo,
    SaveDock,
    SaveMap,
    SetPatrolDwell,
    ShutdownHost,
    StartCharging,
    StartMapping,
    StartNavigation,
    StartPatrol,
    Stop,
    StopCharging,
    StopMapping,
    StopNavigation,
    StopPatrol,
    TurnLeft,
    TurnRight,
    UpdateMap,
)

HEADER = bytes.fromhex("cdebd7")

# --- commands (docs/protocol.md §2) ------------------------------------------------------------

#: (command, frame as hex) — every command class appears at least once.
COMMAND_VECTORS: list[tuple[Command, str]] = [
    (StartNavigation(), "cdebd7 02 6d 00"),
    (StopNavigation(), "cdebd7 02 6d 04"),
    (Goto(0), "cdebd7 02 67 00"),
    (Goto(3), "cdebd7 02 67 03"),
    (Goto(255), "cdebd7 02 67 ff"),
    (Pause(), "cdebd7 02 69 00"),
    (Resume(), "cdebd7 02 69 01"),
    (Cancel(), "cdebd7 02 69 02"),
    # 1.5 = 0x3fc00000, -2.0 = 0xc0000000, little-endian
    (AddTarget(1.5, -2.0), "cdebd7 0a 67 69 0000c03f 000000c0"),
    # 0.0 and 100.25 = 0x42c88000
    (AddTarget(0.0, 100.25), "cdebd7 0a 67 69 00000000 0080c842"),
    (ResetTargets(), "cdebd7 03 67 72 00"),
    (Forward(50), "cdebd7 02 66 32"),
    (Forward(100), "cdebd7 02 66 64"),
    (Backward(100), "cdebd7 02 62 64"),
    (TurnLeft(0), "cdebd7 02 63 00"),
    (TurnRight(25), "cdebd7 02 64 19"),
    (Stop(), "cdebd7 02 73 64"),
    (Stop(0), "cdebd7 02 73 00"),
    (ShutdownHost(), "cdebd7 02 aa 44"),
    (RotateTo(90), "cdebd7 03 61 00 5a"),
    (RotateTo(-45), "cdebd7 03 61 01 2d"),
    (RotateTo(180), "cdebd7 03 61 00 b4"),
    (RotateTo(-180), "cdebd7 03 61 01 b4"),
    (RotateTo(0), "cdebd7 03 61 00 00"),
    (StartPatrol(), "cdebd7 02 6d 05"),
    (StopPatrol(), "cdebd7 02 6d 06"),
    (SetPatrolDwell(30), "cdebd7 03 6d 05 1e"),
    (SetPatrolDwell(255), "cdebd7 03 6d 05 ff"),
    (StartMapping(), "cdebd7 02 56 00"),
    (StopMapping(), "cdebd7 02 56 01"),
    (SaveMap(), "cdebd7 02 56 02"),
    (UpdateMap(), "cdebd7 02 56 03"),
    (StartCharging(), "cdebd7 02 6a 00"),
    (StopCharging(), "cdebd7 02 6a 01"),
    (SaveDock(), "cdebd7 02 6a 02"),
    (Greeting(True), "cdebd7 02 48 00"),
    (Greeting(False), "cdebd7 02 48 01"),
    (RawCommand(b"\x01\x02\x03"), "cdebd7 03 01 02 03"),
    (RawCommand(b"z"), "cdebd7 01 7a"),
]


def command_frame(hex_text: str) -> bytes:
    """The bytes of a hex vector (spaces ignored)."""
    return bytes.fromhex(hex_text.replace(" ", ""))


# --- status frames (docs/protocol.md §1) -------------------------------------------------------

#: v2 struct, fields 1-21: 7 ints, power f, target_num_id i, target_status i,
#: target_distance f, angle_goal_status i, 4 speed floats, time_stamp I, 3 pose floats, busy i.
V2_FORMAT = "<iiiiiiifiififfffIfffi"
#: v1 (2018-03): nav, visual, power f, target id, target status, distance f, angle goal,
#: 4 speed floats, time_stamp I.
V1_FORMAT = "<iifiififfffI"
#: v1_charge: nav, visual, charge, power f, target id, target status, distance f, angle goal,
#: 4 speed floats (no time_stamp).
V1_CHARGE_FORMAT = "<iiifiififfff"

V2_NAMES = (
    "nav_status", "visual_status", "map_status", "gc_status", "gba_status", "charge_status",
    "loop_status", "power", "target_num_id", "target_status", "target_distance",
    "angle_goal_status", "control_speed_x", "control_speed_theta", "current_speed_x",
    "current_speed_theta", "time_stamp", "current_pose_x", "current_pose_y", "current_angle",
    "busy_status",
)  # fmt: skip
V1_NAMES = (
    "nav_status", "visual_status", "power", "target_num_id", "target_status",
    "target_distance", "angle_goal_status", "control_speed_x", "control_speed_theta",
    "current_speed_x", "current_speed_theta", "time_stamp",
)  # fmt: skip
V1_CHARGE_NAMES = (
    "nav_status", "visual_status", "charge_status", "power", "target_num_id", "target_status",
    "target_distance", "angle_goal_status", "control_speed_x", "control_speed_theta",
    "current_speed_x", "current_speed_theta",
)  # fmt: skip

#: docs/protocol.md §1 example: robot idle, firmware defaults, time_stamp = 1 (verbatim).
V2_EXAMPLE = bytes.fromhex(
    "cdebd755" + "00" * 32 + "ffffffff"
    "ffffffff"
    "000080bf"
    "ffffffff" + "00" * 16 + "01000000" + "00" * 16 + "00"
)
V2_EXAMPLE_STATUS = GalileoStatus(
    layout=StatusLayout.V2,
    nav_status=0, visual_status=0, map_status=0, gc_status=0, gba_status=0, charge_status=0,
    loop_status=0, power=0.0, target_num_id=-1, target_status=-1, target_distance=-1.0,
    angle_goal_status=-1, control_speed_x=0.0, control_speed_theta=0.0, current_speed_x=0.0,
    current_speed_theta=0.0, time_stamp=1, current_pose_x=0.0, current_pose_y=0.0,
    current_angle=0.0, busy_status=0,
)  # fmt: skip


def _status(
    layout: StatusLayout, names: tuple[str, ...], values: tuple[int | float, ...]
) -> GalileoStatus:
    return GalileoStatus(layout=layout, **dict(zip(names, values, strict=True)))


#: A busy v2 robot: every field distinct and non-default (all floats exact in float32).
V2_ACTIVE_VALUES = (
    1, 2, 1, 1, 0, 3, 1, 24.5, 7, 1, 3.25, 0, 0.5, -0.25, 0.375, -0.125, 5, 1.5, -2.75,
    0.5, 1,
)  # fmt: skip
V2_ACTIVE = HEADER + b"\x55" + struct.pack(V2_FORMAT, *V2_ACTIVE_VALUES) + b"\x00"
V2_ACTIVE_STATUS = _status(StatusLayout.V2, V2_NAMES, V2_ACTIVE_VALUES)

V1_VALUES = (1, 1, 12.5, 4, 0, 0.004999999888241291, 1, 0.25, -0.5, 0.125, 0.0625, 77)
V1_FRAME = HEADER + b"\x31" + struct.pack(V1_FORMAT, *V1_VALUES) + b"\x00"
V1_STATUS = _status(StatusLayout.V1, V1_NAMES, V1_VALUES)

V1_CHARGE_VALUES = (1, 2, 1, 26.0, 2, 2, 1.75, -1, 0.75, 0.0, -0.375, 0.25)
V1_CHARGE_FRAME = HEADER + b"\x31" + struct.pack(V1_CHARGE_FORMAT, *V1_CHARGE_VALUES) + b"\x00"
V1_CHARGE_STATUS = _status(StatusLayout.V1_CHARGE, V1_CHARGE_NAMES, V1_CHARGE_VALUES)


def _truncated(values: tuple[int | float, ...]) -> bytes:
    # Firmware bug (docs/protocol.md §1 v2_truncated): length byte 0x55 but only the first
    # 49 payload bytes, no terminator.
    return HEADER + b"\x55" + struct.pack(V2_FORMAT, *values)[:49]


#: Two back-to-back v2_truncated frames; the second has power 0.0 (a stale reading),
#: so its byte 35 is 00 and only the header check can rule out a v2 reading of the first.
V2_TRUNCATED_VALUES_A = (
    1, 1, 0, 1, 1, 4, 0, 23.75, 9, 2, 0.5, 1, 2.5, 0.0, 0.0, 0.0, 0, 0.0, 0.0, 0.0, 0,
)  # fmt: skip
V2_TRUNCATED_VALUES_B = (
    1, 2, 1, 0, 0, 1, 1, 0.0, 10, 1, 7.25, 0, -3.0, 0.0, 0.0, 0.0, 0, 0.0, 0.0, 0.0, 0,
)  # fmt: skip
V2_TRUNCATED_A = _truncated(V2_TRUNCATED_VALUES_A)
V2_TRUNCATED_B = _truncated(V2_TRUNCATED_VALUES_B)
V2_TRUNCATED_STATUS_A = _status(
    StatusLayout.V2_TRUNCATED, V2_NAMES[:12], V2_TRUNCATED_VALUES_A[:12]
)
V2_TRUNCATED_STATUS_B = _status(
    StatusLayout.V2_TRUNCATED, V2_NAMES[:12], V2_TRUNCATED_VALUES_B[:12]
)

#: (name, frame, expected status) for every single-frame golden status vector.
STATUS_VECTORS: list[tuple[str, bytes, GalileoStatus]] = [
    ("v2_example", V2_EXAMPLE, V2_EXAMPLE_STATUS),
    ("v2_active", V2_ACTIVE, V2_ACTIVE_STATUS),
    ("v1", V1_FRAME, V1_STATUS),
    ("v1_charge", V1_CHARGE_FRAME, V1_CHARGE_STATUS),
    ("v2_truncated_a", V2_TRUNCATED_A, V2_TRUNCATED_STATUS_A),
    ("v2_truncated_b", V2_TRUNCATED_B, V2_TRUNCATED_STATUS_B),
]


# --- hypothesis strategies ------------------------------------------------------------------

V1, V1C, V2T, V2 = (
    StatusLayout.V1,
    StatusLayout.V1_CHARGE,
    StatusLayout.V2_TRUNCATED,
    StatusLayout.V2,
)
ALL_LAYOUTS = [V1, V1C, V2T, V2]
FIELDS_OF = {V1: V1_NAMES, V1C: V1_CHARGE_NAMES, V2T: V2_NAMES[:12], V2: V2_NAMES}
LENGTH_BYTE = {V1: 0x31, V1C: 0x31, V2T: 0x55, V2: 0x55}

I32 = st.integers(-(2**31), 2**31 - 1)
FLOAT32 = st.floats(width=32, allow_nan=False)
_TYPE_OF = dict(zip(V2_NAMES, V2_FORMAT[1:], strict=True))
_BY_TYPE = {
    "i": st.one_of(st.integers(-2, 6), I32),  # mostly protocol values, sometimes anything
    "f": FLOAT32,
    "I": st.integers(0, 2**32 - 1),
}


def statuses(
    layout: StatusLayout, **overrides: st.SearchStrategy[object]
) -> st.SearchStrategy[GalileoStatus]:
    """Statuses holding exactly the fields of ``layout``, every value exact in its wire type."""
    fields = {name: overrides.get(name, _BY_TYPE[_TYPE_OF[name]]) for name in FIELDS_OF[layout]}
    return st.fixed_dictionaries(fields).map(lambda d: GalileoStatus(layout=layout, **d))


def unambiguous(layout: StatusLayout) -> st.SearchStrategy[GalileoStatus]:
    """Statuses whose 0x31 layout is clear from content (docs/protocol.md §1, field 3)."""
    if layout is V1:  # int32 bits of power outside -1..5 (0.0, denormals and one NaN are in)
        return statuses(layout, power=FLOAT32.map(lambda p: p if abs(p) > 1e-30 else 12.5))
    if layout is V1C:
        return statuses(layout, charge_status=st.sampled_from([-1, 1, 2, 3, 4, 5]))
    return statuses(layout)


def next_header(layout: StatusLayout) -> bytes:
    """The first four bytes of a following frame of ``layout``."""
    return HEADER + bytes((LENGTH_BYTE[layout],))
