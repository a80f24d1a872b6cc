"""Device side of the protocol: the firmware's command parser, for simulators and tests."""

from __future__ import annotations

import struct
from dataclasses import dataclass

from ..errors import InvalidArgument
from ..models import GalileoStatus, StatusLayout
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

__all__ = ["CommandDecoder", "CommandDecoderStats", "encode_status", "parse_payload"]

_FIXED: dict[bytes, type[_Fixed]] = {
    cls.data: cls for cls in COMMAND_TYPES.values() if issubclass(cls, _Fixed)
}
_PERCENT: dict[int, type[_Percent]] = {
    cls.code: cls for cls in COMMAND_TYPES.values() if issubclass(cls, _Percent)
}
_TWO_F32 = struct.Struct("<ff")


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
    """Byte-wise parser with the firmware's rules (PROTOCOL.md §2, parser note)."""

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


def encode_status(status: GalileoStatus, layout: StatusLayout | str | None = None) -> bytes:
    """Encode a status as the robot sends it in ``layout`` (default: the status's own)."""
    name = StatusLayout(layout) if layout is not None else status.layout
    if name is StatusLayout.ROS:
        name = StatusLayout.V2
    target = LAYOUTS[name]
    source = LAYOUTS[StatusLayout.V2] if name is StatusLayout.V2_TRUNCATED else target
    values = []
    for field in source.fields:
        value = getattr(status, field)
        values.append(V2_DEFAULTS[field] if value is None else value)
    payload = source.struct.pack(*values)
    if name is StatusLayout.V2_TRUNCATED:
        payload = payload[: target.frame_size - len(HEADER) - 1]
    tail = b"\x00" if target.terminated else b""
    return HEADER + bytes((target.length_byte,)) + payload + tail
