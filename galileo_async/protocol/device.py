"""Device side of the protocol: the firmware's command parser and status encoder (sim, tests)."""

from __future__ import annotations

import struct
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from operator import itemgetter
from typing import TYPE_CHECKING, Any

from .._wire import STATUS_FIELDS, StatusLayout
from ..errors import InvalidArgument
from .commands import (
    COMMAND_TYPES,
    MAX_COMMAND_PAYLOAD,
    AddTarget,
    Command,
    Goto,
    Greeting,
    RawCommand,
    RotateTo,
    SetPatrolDwell,
    Stop,
    _Fixed,
    _Percent,
)
from .layouts import HEADER, LAYOUTS, V2_DEFAULTS
from .udp import UDP_LAYOUTS, UDP_SOURCE_FIELDS, pack_udp_payload

if TYPE_CHECKING:
    from ..models import GalileoStatus

__all__ = [
    "CommandDecoder",
    "CommandDecoderStats",
    "DatagramCommandDecoder",
    "StatusEncoder",
    "encode_status",
    "parse_payload",
]

_FIXED: dict[bytes, type[_Fixed]] = {
    cls.data: cls for cls in COMMAND_TYPES.values() if issubclass(cls, _Fixed)
}
_PERCENT: dict[int, type[_Percent]] = {
    cls.code: cls for cls in COMMAND_TYPES.values() if issubclass(cls, _Percent)
}
_TWO_F32 = struct.Struct("<ff")
_U32 = struct.Struct("<I")


def parse_payload(payload: bytes) -> Command:
    """Turn a command payload into its command object; anything else becomes RawCommand."""
    fixed = _FIXED.get(payload)
    if fixed is not None:
        return fixed()
    try:
        return _parse_with_arguments(payload)
    except InvalidArgument:
        return RawCommand(payload)


def _parse_with_arguments(payload: bytes) -> Command:
    code, rest = payload[0], payload[1:]
    if len(rest) == 1:
        (value,) = rest
        if code == ord("g"):
            return Goto(value)
        if code in _PERCENT:
            return _PERCENT[code](value)
        if code == ord("s"):
            return Stop(value)
        if code == ord("H") and value in (0, 1):
            return Greeting(value == 0)
    elif code == ord("m") and len(rest) == 2 and rest[0] == 5:
        return SetPatrolDwell(rest[1])
    elif code == ord("a") and len(rest) == 2 and rest[0] in (0, 1):
        return RotateTo(-rest[1] if rest[0] == 1 else rest[1])
    elif payload[:2] == b"gi" and len(payload) == 2 + _TWO_F32.size:
        x, y = _TWO_F32.unpack_from(payload, 2)
        return AddTarget(x, y)
    raise InvalidArgument("not a known command")


@dataclass
class CommandDecoderStats:
    """Counters of the device-side parser."""

    commands: int = 0
    aborted: int = 0
    bad_lengths: int = 0


class CommandDecoder:
    """Byte-wise parser with the firmware's rules (docs/protocol.md §2, parser note)."""

    def __init__(self) -> None:
        self._window = b""
        self._expected: int | None = None  # payload length once the length byte is read
        self._awaiting_length = False
        self._payload = bytearray()
        self.stats = CommandDecoderStats()

    def feed(self, data: bytes) -> list[Command]:
        """Consume bytes; return the commands completed in them, in order."""
        out: list[Command] = []
        for byte in data:
            self._window = (self._window + bytes((byte,)))[-3:]
            if self._window == HEADER:
                # A header anywhere, even inside a payload, aborts what was being read.
                if self._expected is not None and self._payload:
                    self.stats.aborted += 1
                self._payload.clear()
                self._expected = None
                self._awaiting_length = True
                continue
            if self._awaiting_length:
                self._awaiting_length = False
                if 1 <= byte <= MAX_COMMAND_PAYLOAD:
                    self._expected = byte
                else:
                    self.stats.bad_lengths += 1
                continue
            if self._expected is None:
                continue
            self._payload.append(byte)
            if len(self._payload) == self._expected:
                out.append(parse_payload(bytes(self._payload)))
                self.stats.commands += 1
                self._payload.clear()
                self._expected = None
        return out


class DatagramCommandDecoder:
    """The UDP port's command parser (ReqParser; docs/protocol.md §7.5), carry-over and all.

    Splits on every header; a piece is a frame only if its length byte counts exactly the
    bytes up to the next header or the datagram's end. The datagram's last piece, when not
    a frame, is kept and completed by the next datagram's leading bytes; a later whole
    frame does not clear it, a datagram ending in a bare header does. Empty frames
    (``cd eb d7 00``) are valid and yield nothing.
    """

    def __init__(self) -> None:
        self._carried = b""
        self.stats = CommandDecoderStats()

    def feed(self, datagram: bytes) -> list[Command]:
        """The commands of one datagram, in order."""
        pieces = datagram.split(HEADER)
        pieces = (self._carried + pieces[0]).split(HEADER) + pieces[1:]
        out: list[Command] = []
        for piece in pieces:
            if piece and len(piece) == piece[0] + 1:
                if len(piece) > 1:
                    out.append(parse_payload(piece[1:]))
            elif piece:
                self.stats.bad_lengths += 1
        last = pieces[-1]
        if not last or len(last) != last[0] + 1:
            self._carried = last
        self.stats.commands += len(out)
        return out


class StatusEncoder:
    """Status values → frames of one layout as the robot sends them (serial and UDP layouts)."""

    __slots__ = (
        "_defaults", "_extra", "_frame", "_last", "_pack", "_pick", "_prefix", "_size",
        "_stamp_at", "_tail",
    )  # fmt: skip

    def __init__(self, layout: StatusLayout | str, fields: Sequence[str] = STATUS_FIELDS) -> None:
        """Values come in ``fields`` order; a wire field not among them is sent as its default."""
        name = StatusLayout(layout)
        if name is StatusLayout.ROS:  # a ROS status has the v2 fields
            name = StatusLayout.V2
        self._stamp_at: int | None = None
        source_fields: tuple[str, ...]
        if name in UDP_LAYOUTS:
            # The UDP frame packs a flags byte from five fields (docs/protocol.md §7.2).
            udp = UDP_LAYOUTS[name]
            source_fields = UDP_SOURCE_FIELDS
            self._pack: Callable[..., bytes] = lambda *values: pack_udp_payload(name, values)
            self._prefix = HEADER + bytes((udp.length_byte,))
            self._tail = b""
            self._size = udp.struct.size
        else:
            target = LAYOUTS[name]
            # The truncated layout is the v2 struct cut short (docs/protocol.md §1, v2_truncated).
            source = LAYOUTS[StatusLayout.V2] if name is StatusLayout.V2_TRUNCATED else target
            source_fields = source.fields
            self._pack = source.struct.pack
            self._prefix = HEADER + bytes((target.length_byte,))
            self._tail = b"\x00" if target.terminated else b""
            self._size = target.frame_size - len(self._prefix) - len(self._tail)
            if "time_stamp" in target.fields:
                self._stamp_at = len(self._prefix) + 4 * target.fields.index("time_stamp")
        index = {field: i for i, field in enumerate(fields)}
        missing = [field for field in source_fields if field not in index]
        index |= {field: len(fields) + i for i, field in enumerate(missing)}
        self._extra = tuple(V2_DEFAULTS[field] for field in missing)
        self._defaults = tuple(V2_DEFAULTS[field] for field in source_fields)
        self._pick = itemgetter(*(index[field] for field in source_fields))
        self._last: tuple[Any, ...] | None = None
        self._frame = bytearray()

    def frame(self, values: Sequence[Any]) -> bytes:
        """The frame of ``values``, a None among them sent as its field's default; stateless."""
        picked = self._pick((*values, *self._extra))
        if None in picked:
            picked = tuple(
                d if v is None else v for v, d in zip(picked, self._defaults, strict=True)
            )
        return self._build(picked)

    def encode(self, values: tuple[Any, ...], time_stamp: int | None = None) -> bytes:
        """The frame of ``values`` (no None) with ``time_stamp``; repacks only on a change."""
        if values != self._last:
            self._frame = bytearray(self._build(self._pick((*values, *self._extra))))
            self._last = values
        if time_stamp is not None and self._stamp_at is not None:
            _U32.pack_into(self._frame, self._stamp_at, time_stamp & 0xFFFFFFFF)
        return bytes(self._frame)

    def _build(self, picked: tuple[Any, ...]) -> bytes:
        return self._prefix + self._pack(*picked)[: self._size] + self._tail


# One stateless encoder per layout for encode_status (frame() keeps no state).
_ENCODERS = {layout: StatusEncoder(layout) for layout in StatusLayout}


def encode_status(status: GalileoStatus, layout: StatusLayout | str | None = None) -> bytes:
    """Encode a status as the robot sends it in ``layout`` (default: the status's own)."""
    encoder = _ENCODERS[status.layout if layout is None else StatusLayout(layout)]
    return encoder.frame([getattr(status, field) for field in STATUS_FIELDS])
