"""Byte layouts of the four status frame formats (docs/protocol.md §1)."""

from __future__ import annotations

import struct
from dataclasses import dataclass
from typing import Any

from .._wire import (
    AngleGoalStatus,
    ChargeStatus,
    MapStatus,
    NavStatus,
    StatusLayout,
    TargetStatus,
    VisualStatus,
)

__all__ = ["HEADER", "LAYOUTS", "LENGTH_V1", "LENGTH_V2", "V2_DEFAULTS", "Layout"]

#: Every frame, in both directions, starts with these three bytes.
HEADER = b"\xcd\xeb\xd7"
LENGTH_V1 = 0x31
LENGTH_V2 = 0x55

# Wire type per field of the v2 struct: i int32, f float32, I uint32.
_TYPES: dict[str, str] = {
    "nav_status": "i",
    "visual_status": "i",
    "map_status": "i",
    "gc_status": "i",
    "gba_status": "i",
    "charge_status": "i",
    "loop_status": "i",
    "power": "f",
    "target_num_id": "i",
    "target_status": "i",
    "target_distance": "f",
    "angle_goal_status": "i",
    "control_speed_x": "f",
    "control_speed_theta": "f",
    "current_speed_x": "f",
    "current_speed_theta": "f",
    "time_stamp": "I",
    "current_pose_x": "f",
    "current_pose_y": "f",
    "current_angle": "f",
    "busy_status": "i",
}

#: Enum type per enum-valued field; the decoder maps raw ints through these.
ENUM_FIELDS: dict[str, type[Any]] = {
    "nav_status": NavStatus,
    "visual_status": VisualStatus,
    "map_status": MapStatus,
    "charge_status": ChargeStatus,
    "target_status": TargetStatus,
    "angle_goal_status": AngleGoalStatus,
}

#: What the firmware sends before its first real status (docs/protocol.md §1).
V2_DEFAULTS: dict[str, int | float] = {
    name: (0.0 if kind == "f" else 0) for name, kind in _TYPES.items()
} | {"target_num_id": -1, "target_status": -1, "angle_goal_status": -1, "target_distance": -1.0}


@dataclass(frozen=True)
class Layout:
    """One wire format: which fields, packed how, in how many bytes."""

    name: StatusLayout
    length_byte: int
    fields: tuple[str, ...]
    frame_size: int
    terminated: bool

    @property
    def struct(self) -> struct.Struct:
        """Struct for the fields, little-endian, starting at payload offset 0."""
        return _structs[self.name]


def _layout(
    name: StatusLayout, length_byte: int, fields: tuple[str, ...], *, terminated: bool = True
) -> Layout:
    size = 4 + 4 * len(fields) + (1 if terminated else 0)
    return Layout(name, length_byte, fields, size, terminated)


_V2_FIELDS = tuple(_TYPES)
_V1_FIELDS = (
    "nav_status",
    "visual_status",
    "power",
    "target_num_id",
    "target_status",
    "target_distance",
    "angle_goal_status",
    "control_speed_x",
    "control_speed_theta",
    "current_speed_x",
    "current_speed_theta",
    "time_stamp",
)
_V1_CHARGE_FIELDS = (
    "nav_status",
    "visual_status",
    "charge_status",
    *_V1_FIELDS[2:11],
)

LAYOUTS: dict[StatusLayout, Layout] = {
    StatusLayout.V1: _layout(StatusLayout.V1, LENGTH_V1, _V1_FIELDS),
    StatusLayout.V1_CHARGE: _layout(StatusLayout.V1_CHARGE, LENGTH_V1, _V1_CHARGE_FIELDS),
    # A firmware bug sent only the first 49 payload bytes: fields 1-12 and one byte of
    # field 13, with no terminator (docs/protocol.md §1, v2_truncated).
    StatusLayout.V2_TRUNCATED: Layout(
        StatusLayout.V2_TRUNCATED, LENGTH_V2, _V2_FIELDS[:12], 4 + 49, terminated=False
    ),
    StatusLayout.V2: _layout(StatusLayout.V2, LENGTH_V2, _V2_FIELDS),
}

_structs: dict[StatusLayout, struct.Struct] = {
    name: struct.Struct("<" + "".join(_TYPES[f] for f in layout.fields))
    for name, layout in LAYOUTS.items()
}
