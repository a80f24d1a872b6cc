"""The status frames of the robot's UDP port 20001 (docs/protocol.md §7): layouts, decoder.

Two layouts, told apart by the length byte: ``udp_v2`` (0x2c, 48 bytes, with
target_distance) and ``udp_v1`` (0x28, 44 bytes, without). The environment-sensor frame
(0x20, 36 bytes) shares the port and is skipped. The frame packs nav/map/visual/gc/gba
into one flags byte; fields it does not carry decode as None.
"""

from __future__ import annotations

import struct
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from .._wire import ChargeStatus, MapStatus, NavStatus, StatusLayout, TargetStatus
from .._wire import VisualStatus as Visual
from .layouts import HEADER
from .status import DecoderStats

if TYPE_CHECKING:
    from ..models import GalileoStatus

__all__ = [
    "ENV_FRAME_SIZE",
    "FLAG_GBA",
    "FLAG_GC",
    "FLAG_MAPPING",
    "FLAG_NAVIGATING",
    "FLAG_TRACKING",
    "FLAG_VISUAL_ON",
    "LENGTH_ENV",
    "UDP_LAYOUTS",
    "UDP_SOURCE_FIELDS",
    "UdpLayout",
    "UdpStatusDecoder",
    "encode_env_frame",
    "flags_of",
    "pack_udp_payload",
]

#: Length byte of the environment-sensor frame (temperature … noise, 8 x f32): skipped.
LENGTH_ENV = 0x20
ENV_FRAME_SIZE = 4 + LENGTH_ENV

# The flags byte (udp_status_service.py): one bit per condition on the robot's status.
FLAG_NAVIGATING = 0x01  # nav_status == 1
FLAG_MAPPING = 0x02  # map_status != 0
FLAG_VISUAL_ON = 0x04  # visual_status != -1
FLAG_TRACKING = 0x08  # visual_status == 1
FLAG_GC = 0x10  # gc_status == 1
FLAG_GBA = 0x20  # gba_status == 1

#: The status fields a UDP frame is packed from, in the order the packer takes them.
UDP_SOURCE_FIELDS = (
    "current_pose_x", "current_pose_y", "power", "nav_status", "map_status", "visual_status",
    "gc_status", "gba_status", "current_angle", "target_status", "target_num_id",
    "charge_status", "loop_status", "target_distance",
)  # fmt: skip


@dataclass(frozen=True)
class UdpLayout:
    """One UDP status layout: its length byte, its size and the status fields it carries."""

    name: StatusLayout
    length_byte: int
    #: x, y, reserved (0.0), power, flags, 3 pad bytes, angle, target_status,
    #: target_num_id, charge_status, loop_status[, target_distance]; after the length byte.
    struct: struct.Struct
    #: The GalileoStatus fields this layout fills; every other field is None.
    fields: tuple[str, ...]

    @property
    def frame_size(self) -> int:
        """Bytes in one frame: header, length byte, payload (no terminator)."""
        return 4 + self.struct.size


_V1_FIELDS = (
    "nav_status", "visual_status", "map_status", "gc_status", "gba_status", "charge_status",
    "loop_status", "power", "target_num_id", "target_status", "current_pose_x",
    "current_pose_y", "current_angle",
)  # fmt: skip

UDP_LAYOUTS: dict[StatusLayout, UdpLayout] = {
    StatusLayout.UDP_V1: UdpLayout(
        StatusLayout.UDP_V1, 0x28, struct.Struct("<4fB3xf4i"), _V1_FIELDS
    ),
    StatusLayout.UDP_V2: UdpLayout(
        StatusLayout.UDP_V2, 0x2C, struct.Struct("<4fB3xf4if"), (*_V1_FIELDS, "target_distance")
    ),
}
_BY_LENGTH = {layout.length_byte: layout for layout in UDP_LAYOUTS.values()}


def flags_of(nav: Any, mapping: Any, visual: Any, gc: Any, gba: Any) -> int:
    """The flags byte the robot sends for these status values (udp_status_service.py)."""
    return (
        (FLAG_NAVIGATING if nav == 1 else 0)
        | (FLAG_MAPPING if mapping else 0)
        | (FLAG_VISUAL_ON if visual != -1 else 0)
        | (FLAG_TRACKING if visual == 1 else 0)
        | (FLAG_GC if gc == 1 else 0)
        | (FLAG_GBA if gba == 1 else 0)
    )


def pack_udp_payload(layout: StatusLayout, values: Sequence[Any]) -> bytes:
    """The payload (after the length byte) of ``values`` in UDP_SOURCE_FIELDS order."""
    x, y, power, nav, mapping, visual, gc, gba, angle, target, target_id, charge, loop, distance = (
        values
    )
    flags = flags_of(nav, mapping, visual, gc, gba)
    head = (x, y, 0.0, power, flags, angle, target, target_id, charge, loop)
    if layout is StatusLayout.UDP_V2:
        return UDP_LAYOUTS[layout].struct.pack(*head, distance)
    return UDP_LAYOUTS[layout].struct.pack(*head)


def _visual(flags: int) -> Visual:
    # Two bits for four states: "lost" (2) and "not initialised" (0) both read 0x04
    # without 0x08. Taken as not initialised, so nothing that needs the visual system
    # initialised is sent on a robot that may not be (docs/protocol.md §7.2).
    if flags & FLAG_TRACKING:
        return Visual.TRACKING
    return Visual.NOT_INITIALISED if flags & FLAG_VISUAL_ON else Visual.OFF


_NAV = (NavStatus.CLOSED, NavStatus.OPEN)
_MAP = (MapStatus.IDLE, MapStatus.MAPPING)


def _status(layout: UdpLayout, values: tuple[Any, ...]) -> GalileoStatus:
    x, y, _reserved, power, flags, angle, target, target_id, charge, loop = values[:10]
    fields: dict[str, Any] = {
        "layout": layout.name,
        "nav_status": _NAV[flags & FLAG_NAVIGATING],
        "visual_status": _visual(flags),
        "map_status": _MAP[(flags & FLAG_MAPPING) >> 1],
        "gc_status": (flags & FLAG_GC) >> 4,
        "gba_status": (flags & FLAG_GBA) >> 5,
        "charge_status": ChargeStatus(charge),
        "loop_status": loop,
        "power": power,
        "target_num_id": target_id,
        "target_status": TargetStatus(target),
        "current_pose_x": x,
        "current_pose_y": y,
        "current_angle": angle,
    }
    if len(values) > 10:
        fields["target_distance"] = values[10]
    return _trusted(fields)


def _first_trusted(fields: dict[str, Any]) -> GalileoStatus:
    """Load the status builder (and pydantic with GalileoStatus) on the first datagram."""
    global _trusted
    from ._build import trusted_status

    _trusted = trusted_status
    return trusted_status(fields)


_trusted: Callable[[dict[str, Any]], GalileoStatus] = _first_trusted


class UdpStatusDecoder:
    """Datagrams in, GalileoStatus out; each datagram holds whole frames, none carried over.

    A frame is taken when its length byte names a UDP layout and it ends where the
    datagram or the next header does; environment frames are counted and skipped;
    anything else is counted as discarded. Never raises on bad input.
    """

    __slots__ = ("skipped_frames", "stats")

    def __init__(self, *, stats: DecoderStats | None = None) -> None:
        """Count into ``stats`` (a new DecoderStats if None)."""
        self.stats = DecoderStats() if stats is None else stats
        #: Valid frames that carry no status (the environment-sensor frame).
        self.skipped_frames = 0

    def feed(self, datagram: bytes | bytearray | memoryview) -> list[GalileoStatus]:
        """Every status frame in one datagram, in order."""
        data = bytes(datagram)
        size = len(data)
        out: list[GalileoStatus] = []
        pos = 0
        while pos < size:
            start = data.find(HEADER, pos)
            if start < 0:
                self._discard(size - pos)
                break
            if start > pos:
                self._discard(start - pos)
            end = start + 4 + data[start + 3] if start + 3 < size else size + 1
            whole = end == size or (end < size and data.startswith(HEADER, end))
            layout = _BY_LENGTH.get(data[start + 3]) if whole else None
            if layout is not None:
                out.append(_status(layout, layout.struct.unpack_from(data, start + 4)))
                self.stats.layout = layout.name
            elif whole and data[start + 3] == LENGTH_ENV:
                self.skipped_frames += 1
            else:
                self._discard(len(HEADER))
                pos = start + len(HEADER)
                continue
            pos = end
        self.stats.frames += len(out)
        return out

    def _discard(self, count: int) -> None:
        self.stats.bytes_discarded += count
        self.stats.resyncs += 1


_ENV = struct.Struct("<8f")


def encode_env_frame(values: Sequence[float] = (0.0,) * 8) -> bytes:
    """The environment-sensor frame (device side) of temperature, rh, smoke, pm…, lel, noise."""
    return HEADER + bytes((LENGTH_ENV,)) + _ENV.pack(*values)
