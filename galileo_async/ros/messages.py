"""The Galileo ROS messages: GalileoNativeCmds encoding and GalileoStatus decoding by name."""

from __future__ import annotations

import struct
from collections.abc import Callable
from typing import Any

from ..models import STATUS_FIELDS, GalileoStatus, StatusLayout
from ..protocol._build import trusted_status
from ..protocol.commands import Command
from ..protocol.layouts import ENUM_FIELDS
from ..protocol.names import ROS_FIELD_NAMES
from .msgdef import (
    HEADER_DEFINITION,
    SEPARATOR,
    MessageDefinitionError,
    compile_decoder,
    md5sum,
    parse_full_definition,
)

__all__ = [
    "CMDS_DEFINITION",
    "CMDS_MD5",
    "CMDS_TOPIC",
    "CMDS_TYPE",
    "CMD_VEL_TOPIC",
    "ROS_FIELD_NAMES",
    "STATUS_DEFINITION",
    "STATUS_DEFINITION_13",
    "STATUS_MD5",
    "STATUS_TOPIC",
    "STATUS_TYPE",
    "TWIST_DEFINITION",
    "TWIST_MD5",
    "TWIST_TYPE",
    "StatusMessageDecoder",
    "encode_cmds",
    "encode_twist",
    "full_definition",
]

CMDS_TOPIC = "/galileo/cmds"
STATUS_TOPIC = "/galileo/status"
CMDS_TYPE = "galileo_serial_server/GalileoNativeCmds"
#: Velocity commands for the chassis driver (docs/protocol.md §6.1): only linear.x and angular.z.
CMD_VEL_TOPIC = "/cmd_vel"
TWIST_TYPE = "geometry_msgs/Twist"
STATUS_TYPE = "galileo_serial_server/GalileoStatus"

_HEADER_TEXT = (
    "# Standard metadata for higher-level stamped data types.\n"
    "# sequence ID: consecutively increasing ID\n" + HEADER_DEFINITION
)

#: docs/protocol.md §3: the command bytes after the length byte.
CMDS_DEFINITION = "Header header\nuint32 length\nuint8[] data\n"


_FLOAT_FIELDS = frozenset(
    {
        "power",
        "targetDistance",
        "controlSpeedX",
        "controlSpeedTheta",
        "currentSpeedX",
        "currentSpeedTheta",
        "currentPosX",
        "currentPosY",
        "currentAngle",
    }
)


def _status_text(names: list[str]) -> str:
    lines = ["Header header"]
    lines += [f"{'float32' if n in _FLOAT_FIELDS else 'int32'} {n}" for n in names]
    return "\n".join(lines) + "\n"


#: The final GalileoStatus (docs/protocol.md §3).
STATUS_DEFINITION = _status_text(list(ROS_FIELD_NAMES))
#: The 13-field GalileoStatus of the vendor document (older robots).
STATUS_DEFINITION_13 = _status_text(
    [
        "navStatus",
        "visualStatus",
        "chargeStatus",
        "loopStatus",
        "power",
        "targetNumID",
        "targetStatus",
        "targetDistance",
        "angleGoalStatus",
        "controlSpeedX",
        "controlSpeedTheta",
        "currentSpeedX",
        "currentSpeedTheta",
    ]
)


#: geometry_msgs/Twist with its Vector3 dependency, as a publisher's message_definition.
TWIST_DEFINITION = (
    "Vector3 linear\nVector3 angular\n"
    + SEPARATOR
    + "MSG: geometry_msgs/Vector3\nfloat64 x\nfloat64 y\nfloat64 z\n"
)
_TWIST = struct.Struct("<6d")


def encode_twist(linear: float, angular: float) -> bytes:
    """Serialise a Twist of ``linear`` m/s along x and ``angular`` rad/s about z."""
    return _TWIST.pack(linear, 0.0, 0.0, 0.0, 0.0, angular)


def full_definition(text: str) -> str:
    """A message text followed by the std_msgs/Header dependency, as genpy's _full_text."""
    return text + SEPARATOR + "MSG: std_msgs/Header\n" + _HEADER_TEXT


def _md5(full_name: str, text: str) -> str:
    return md5sum(full_name, parse_full_definition(full_name, full_definition(text)))


CMDS_MD5 = _md5(CMDS_TYPE, CMDS_DEFINITION)
STATUS_MD5 = _md5(STATUS_TYPE, STATUS_DEFINITION)
TWIST_MD5 = md5sum(TWIST_TYPE, parse_full_definition(TWIST_TYPE, TWIST_DEFINITION))
_KNOWN_STATUS = {
    STATUS_MD5: STATUS_DEFINITION,
    _md5(STATUS_TYPE, STATUS_DEFINITION_13): STATUS_DEFINITION_13,
}

_HEADER = struct.Struct("<III")
_U32 = struct.Struct("<I")


def encode_cmds(command: Command, *, seq: int, stamp: float, frame_id: str = "") -> bytes:
    """Serialise a command as GalileoNativeCmds (header, length, data = the payload)."""
    payload = command.payload()
    secs = int(stamp)
    nsecs = min(int((stamp - secs) * 1e9), 999_999_999)
    frame = frame_id.encode()
    return b"".join(
        (
            _HEADER.pack(seq & 0xFFFFFFFF, secs, nsecs),
            _U32.pack(len(frame)),
            frame,
            _U32.pack(len(payload)),
            _U32.pack(len(payload)),
            payload,
        )
    )


class StatusMessageDecoder:
    """Decode GalileoStatus messages of any version, by the field names of its definition."""

    def __init__(self, definition: str | None, md5: str | None = None) -> None:
        """Use the publisher's ``message_definition``, or a known version picked by md5."""
        if not definition:
            if md5 not in _KNOWN_STATUS:
                raise MessageDefinitionError(
                    f"no message_definition and unknown GalileoStatus md5 {md5!r}"
                )
            definition = full_definition(_KNOWN_STATUS[md5])
        specs = parse_full_definition(STATUS_TYPE, definition)
        self.md5 = md5sum(STATUS_TYPE, specs)
        self.field_names = specs[STATUS_TYPE].names
        self._decode = compile_decoder(STATUS_TYPE, specs)
        self._known = [
            (ros, ROS_FIELD_NAMES[ros]) for ros in self.field_names if ros in ROS_FIELD_NAMES
        ]
        self._has_header = "header" in self.field_names
        self._enums: list[tuple[str, Callable[[Any], Any], dict[Any, Any]]] = [
            (ours, ENUM_FIELDS[ours], ENUM_FIELDS[ours]._value2member_map_)
            for _, ours in self._known
            if ours in ENUM_FIELDS
        ]
        self._template: dict[str, Any] = dict.fromkeys(STATUS_FIELDS)
        self._template["layout"] = StatusLayout.ROS

    def decode(self, data: bytes) -> GalileoStatus:
        """Decode one serialised message; raises MessageDefinitionError when malformed."""
        raw = self._decode(data)
        values = self._template.copy()
        for ros, ours in self._known:
            values[ours] = raw[ros]
        for ours, enum_type, members in self._enums:
            value = values[ours]
            member = members.get(value)
            values[ours] = member if member is not None else enum_type(value)
        if self._has_header and isinstance(raw["header"], dict):
            values["time_stamp"] = raw["header"].get("seq")
        return trusted_status(values)
