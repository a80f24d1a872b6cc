"""Command objects (validated at construction) and their byte encoding (docs/protocol.md §2)."""

from __future__ import annotations

import struct
from dataclasses import dataclass
from typing import ClassVar

from .._checks import check_int, check_number
from ..errors import InvalidArgument
from .layouts import HEADER

__all__ = [
    "COMMAND_TYPES",
    "MAX_COMMAND_PAYLOAD",
    "MAX_COORDINATE",
    "AddTarget",
    "Backward",
    "Cancel",
    "Command",
    "Forward",
    "Goto",
    "Greeting",
    "Pause",
    "RawCommand",
    "ResetTargets",
    "Resume",
    "RotateTo",
    "SaveDock",
    "SaveMap",
    "SetPatrolDwell",
    "ShutdownHost",
    "StartCharging",
    "StartMapping",
    "StartNavigation",
    "StartPatrol",
    "Stop",
    "StopCharging",
    "StopMapping",
    "StopNavigation",
    "StopPatrol",
    "TurnLeft",
    "TurnRight",
    "UpdateMap",
    "encode",
    "nudge_coordinates",
]

#: The firmware parser ignores a command whose length byte is 0 or above this.
MAX_COMMAND_PAYLOAD = 20
#: Largest |x| or |y| accepted for a dynamic target, metres.
MAX_COORDINATE = 100_000.0

_F32 = struct.Struct("<f")
_U32 = struct.Struct("<I")


@dataclass(frozen=True, slots=True)
class Command:
    """Base of every command: ``payload()`` is the bytes after the length byte."""

    name: ClassVar[str] = ""

    def __init_subclass__(cls) -> None:
        # No zero-argument super() here: slots=True dataclasses replace the class.
        if not cls.__name__.startswith("_"):
            cls.name = cls.__name__

    def payload(self) -> bytes:
        """The command's bytes after the header and length byte."""
        raise NotImplementedError


@dataclass(frozen=True, slots=True)
class _Fixed(Command):
    """A command without arguments: always the same bytes."""

    data: ClassVar[bytes] = b""

    def payload(self) -> bytes:
        return self.data


@dataclass(frozen=True, slots=True)
class StartNavigation(_Fixed):
    """Start navigation ('m' 0); the firmware ignores a repeat within 5-30 s."""

    data: ClassVar[bytes] = b"m\x00"


# 'm' 4 stops the whole navigation service, patrol included (docs/protocol.md §2.a).
@dataclass(frozen=True, slots=True)
class StopNavigation(_Fixed):
    """Stop navigation, patrol and the goal ('m' 4)."""

    data: ClassVar[bytes] = b"m\x04"


@dataclass(frozen=True, slots=True)
class Pause(_Fixed):
    """Pause the working goal ('i' 0)."""

    data: ClassVar[bytes] = b"i\x00"


@dataclass(frozen=True, slots=True)
class Resume(_Fixed):
    """Resume the paused goal ('i' 1)."""

    data: ClassVar[bytes] = b"i\x01"


@dataclass(frozen=True, slots=True)
class Cancel(_Fixed):
    """Cancel the goal ('i' 2); firmware sets target_num_id to -1."""

    data: ClassVar[bytes] = b"i\x02"


@dataclass(frozen=True, slots=True)
class ResetTargets(_Fixed):
    """Drop every dynamic target, keep the map's own ('g' 'r' 0)."""

    data: ClassVar[bytes] = b"gr\x00"


@dataclass(frozen=True, slots=True)
class ShutdownHost(_Fixed):
    """Power the navigation computer off (0xAA 0x44)."""

    data: ClassVar[bytes] = b"\xaa\x44"


@dataclass(frozen=True, slots=True)
class StartPatrol(_Fixed):
    """Start auto-patrol over all targets ('m' 5); needs navigation."""

    data: ClassVar[bytes] = b"m\x05"


# Firmware stops patrol with 'm' 6; the document's 'm' 4 stops navigation (docs/protocol.md §2.g).
@dataclass(frozen=True, slots=True)
class StopPatrol(_Fixed):
    """Stop auto-patrol and keep navigation ('m' 6)."""

    data: ClassVar[bytes] = b"m\x06"


@dataclass(frozen=True, slots=True)
class StartMapping(_Fixed):
    """Start building a map ('V' 0); also stops navigation."""

    data: ClassVar[bytes] = b"V\x00"


@dataclass(frozen=True, slots=True)
class StopMapping(_Fixed):
    """Stop building the map ('V' 1)."""

    data: ClassVar[bytes] = b"V\x01"


@dataclass(frozen=True, slots=True)
class SaveMap(_Fixed):
    """Save the map ('V' 2); some firmware versions ignore it."""

    data: ClassVar[bytes] = b"V\x02"


@dataclass(frozen=True, slots=True)
class UpdateMap(_Fixed):
    """Update the map ('V' 3)."""

    data: ClassVar[bytes] = b"V\x03"


@dataclass(frozen=True, slots=True)
class StartCharging(_Fixed):
    """Dock and charge ('j' 0): local infrared docking, the robot near the dock, navigating."""

    data: ClassVar[bytes] = b"j\x00"


@dataclass(frozen=True, slots=True)
class StopCharging(_Fixed):
    """Stop charging ('j' 1)."""

    data: ClassVar[bytes] = b"j\x01"


@dataclass(frozen=True, slots=True)
class SaveDock(_Fixed):
    """Save the current pose as the dock position ('j' 2)."""

    data: ClassVar[bytes] = b"j\x02"


@dataclass(frozen=True, slots=True)
class Goto(Command):
    """Go to map target ``target_id`` (0-255) ('g' id)."""

    target_id: int

    def __post_init__(self) -> None:
        check_int("target_id", self.target_id, 0, 255)

    def payload(self) -> bytes:
        return bytes((0x67, self.target_id))


@dataclass(frozen=True, slots=True)
class _Percent(Command):
    """A speed command carrying a percentage 0-100."""

    percent: int
    code: ClassVar[int] = 0

    def __post_init__(self) -> None:
        check_int("percent", self.percent, 0, 100)

    def payload(self) -> bytes:
        return bytes((self.code, self.percent))


@dataclass(frozen=True, slots=True)
class Forward(_Percent):
    """Drive forward at ``percent`` of max speed ('f'); how long it lasts is the chassis's."""

    code: ClassVar[int] = ord("f")


@dataclass(frozen=True, slots=True)
class Backward(_Percent):
    """Drive backward at ``percent`` of max speed ('b')."""

    code: ClassVar[int] = ord("b")


@dataclass(frozen=True, slots=True)
class TurnLeft(_Percent):
    """Turn left at ``percent`` of max angular speed ('c')."""

    code: ClassVar[int] = ord("c")


@dataclass(frozen=True, slots=True)
class TurnRight(_Percent):
    """Turn right at ``percent`` of max angular speed ('d')."""

    code: ClassVar[int] = ord("d")


@dataclass(frozen=True, slots=True)
class Stop(Command):
    """Zero both speeds with ``brake`` 0-100 ('s')."""

    brake: int = 100

    def __post_init__(self) -> None:
        check_int("brake", self.brake, 0, 100)

    def payload(self) -> bytes:
        return bytes((ord("s"), self.brake))


@dataclass(frozen=True, slots=True)
class RotateTo(Command):
    """Rotate to ``degrees`` (-180..180, whole degrees) ('a'); most firmware ignores it."""

    degrees: int

    def __post_init__(self) -> None:
        check_int("degrees", self.degrees, -180, 180)

    def payload(self) -> bytes:
        return bytes((ord("a"), 1 if self.degrees < 0 else 0, abs(self.degrees)))


@dataclass(frozen=True, slots=True)
class SetPatrolDwell(Command):
    """Set the patrol wait at each target, 0-255 s ('m' 5 TT); firmware also starts patrol."""

    seconds: int

    def __post_init__(self) -> None:
        check_int("seconds", self.seconds, 0, 255)

    def payload(self) -> bytes:
        return bytes((ord("m"), 5, self.seconds))


@dataclass(frozen=True, slots=True)
class Greeting(Command):
    """Switch the robot's greeting on or off ('H'; firmware only)."""

    enabled: bool

    def __post_init__(self) -> None:
        if not isinstance(self.enabled, bool):
            raise InvalidArgument(f"enabled must be a bool, got {self.enabled!r}")

    def payload(self) -> bytes:
        return bytes((ord("H"), 0 if self.enabled else 1))


@dataclass(frozen=True, slots=True)
class AddTarget(Command):
    """Append a dynamic target at map coordinates (x, y) metres ('g' 'i' f32 f32)."""

    x: float
    y: float

    def __post_init__(self) -> None:
        check_number("x", self.x, low=-MAX_COORDINATE, high=MAX_COORDINATE)
        check_number("y", self.y, low=-MAX_COORDINATE, high=MAX_COORDINATE)

    def payload(self) -> bytes:
        x, y = nudge_coordinates(self.x, self.y)
        return b"gi" + _F32.pack(x) + _F32.pack(y)


@dataclass(frozen=True, slots=True)
class RawCommand(Command):
    """Any payload of 1-20 bytes, sent as is; must not contain the frame header."""

    data: bytes

    def __post_init__(self) -> None:
        if not isinstance(self.data, (bytes, bytearray)):
            raise InvalidArgument(f"data must be bytes, got {self.data!r}")
        if not 1 <= len(self.data) <= MAX_COMMAND_PAYLOAD:
            size = len(self.data)
            raise InvalidArgument(f"a payload is 1..{MAX_COMMAND_PAYLOAD} bytes, got {size}")
        if HEADER in bytes((len(self.data),)) + self.data:
            raise InvalidArgument("a payload must not contain the frame header CD EB D7")
        object.__setattr__(self, "data", bytes(self.data))

    def payload(self) -> bytes:
        return self.data


def _f32_bits(value: float) -> int:
    return int(_U32.unpack(_F32.pack(value))[0])


def _f32_from_bits(bits: int) -> float:
    return float(_F32.unpack(_U32.pack(bits))[0])


def nudge_coordinates(x: float, y: float) -> tuple[float, float]:
    """Return float32 (x, y), each moved by one ulp while their bytes would contain CD EB D7."""
    # The firmware parser resyncs on a header anywhere, even inside a payload, and would
    # abort the command (docs/protocol.md §2 parser note and §2.d).
    bits = [_f32_bits(x), _f32_bits(y)]
    for _ in range(8):
        data = b"\x0agi" + _U32.pack(bits[0]) + _U32.pack(bits[1])
        where = data.find(HEADER)
        if where < 0:
            break
        which = 0 if where < 7 else 1
        bits[which] += 1  # one ulp away from zero, whatever the sign
    return _f32_from_bits(bits[0]), _f32_from_bits(bits[1])


def encode(command: Command) -> bytes:
    """Frame a command for the wire: header, length byte, payload."""
    payload = command.payload()
    return HEADER + bytes((len(payload),)) + payload


#: Every concrete command type, by name.
COMMAND_TYPES: dict[str, type[Command]] = {
    cls.name: cls
    for cls in (
        StartNavigation, StopNavigation, Goto, Pause, Resume, Cancel, AddTarget, ResetTargets,
        Forward, Backward, TurnLeft, TurnRight, Stop, ShutdownHost, RotateTo, StartPatrol,
        StopPatrol, SetPatrolDwell, StartMapping, StopMapping, SaveMap, UpdateMap,
        StartCharging, StopCharging, SaveDock, Greeting, RawCommand,
    )
}  # fmt: skip
