"""What the Foxglove channels carry besides galileo_async.schemas, without the SDK: the link as
JSON, the services' request schemas, the status schema encoded (docs/observability.md)."""

from __future__ import annotations

import json
import math
from functools import cache
from typing import TYPE_CHECKING, Any

from ..schemas import status_schema

if TYPE_CHECKING:
    from ..robot import MapImage, Robot

__all__ = [
    "LINK_SCHEMA_NAME",
    "MAP_INFO_SCHEMA_NAME",
    "SERVICE_REQUESTS",
    "link_json",
    "link_schema",
    "map_info_json",
    "map_info_schema",
    "service_schema",
    "status_schema_bytes",
    "yaw_quaternion",
]

#: The schema name of the link channels.
LINK_SCHEMA_NAME = "galileo_async.LinkStats"
#: The schema name of the map_info channels.
MAP_INFO_SCHEMA_NAME = "galileo_async.MapInfo"

_NUMBER = {"type": "number"}
_INTEGER = {"type": "integer"}

#: Each service's request: its JSON Schema (an empty object for the calls without arguments).
SERVICE_REQUESTS: dict[str, dict[str, Any]] = {
    "goto": {
        "type": "object",
        "properties": {"target": {**_INTEGER, "minimum": 0, "maximum": 255}},
        "required": ["target"],
        "additionalProperties": False,
    },
    "goto_point": {
        "type": "object",
        "properties": {"x": _NUMBER, "y": _NUMBER},
        "required": ["x", "y"],
        "additionalProperties": False,
    },
    **{
        name: {"type": "object", "properties": {}, "additionalProperties": False}
        for name in ("stop", "cancel", "pause", "resume", "dock")
    },
}


@cache
def status_schema_bytes() -> bytes:
    """The status channels' JSON Schema (galileo_async.schemas.status_schema), encoded once."""
    return json.dumps(status_schema()).encode()


@cache
def link_schema() -> bytes:
    """The JSON Schema of link_json's messages."""
    count = {"type": "integer", "minimum": 0}
    schema = {
        "title": LINK_SCHEMA_NAME,
        "type": "object",
        "properties": {
            "state": {"type": "string", "enum": ["connecting", "up", "stale", "lost", "closed"]},
            "frames": count,
            "lost_frames": count,
            "bytes_discarded": count,
            "resyncs": count,
            "reconnects": count,
            "commands_sent": count,
            "last_frame_age": {"anyOf": [_NUMBER, {"type": "null"}]},
        },
        "required": ["state", "frames", "lost_frames"],
    }
    return json.dumps(schema).encode()


def link_json(robot: Robot) -> bytes:
    """The robot's link now: state, frame and loss counts, seconds since the last frame."""
    link = robot.link
    age = link.last_frame_age
    message = {
        "state": robot.link_state.value,
        "frames": link.frames,
        "lost_frames": link.lost_frames,
        "bytes_discarded": link.bytes_discarded,
        "resyncs": link.resyncs,
        "reconnects": link.reconnects,
        "commands_sent": link.commands_sent,
        "last_frame_age": None if age is None else round(age, 3),
    }
    return json.dumps(message).encode()


@cache
def map_info_schema() -> bytes:
    """The JSON Schema of map_info_json's messages."""
    pixels = {"type": "integer", "minimum": 1}
    schema = {
        "title": MAP_INFO_SCHEMA_NAME,
        "type": "object",
        "properties": {
            "map": {"type": "string"},
            "frame_id": {"type": "string"},
            "origin": {
                "type": "object",
                "properties": {"x": _NUMBER, "y": _NUMBER, "yaw": _NUMBER},
                "required": ["x", "y", "yaw"],
            },
            "width": pixels,
            "height": pixels,
            "resolution": {**_NUMBER, "exclusiveMinimum": 0},
        },
        "required": ["map", "frame_id", "origin", "width", "height", "resolution"],
    }
    return json.dumps(schema).encode()


def map_info_json(name: str, image: MapImage, frame_id: str) -> bytes:
    """Where map ``name``'s image lies: its lower left pixel's pose, size, metres a pixel."""
    x, y, yaw = image.origin
    message = {
        "map": name,
        "frame_id": frame_id,
        "origin": {"x": x, "y": y, "yaw": yaw},
        "width": image.width,
        "height": image.height,
        "resolution": image.resolution,
    }
    return json.dumps(message).encode()


def service_schema(name: str) -> bytes:
    """The JSON Schema of service ``name``'s request."""
    return json.dumps({"title": f"galileo_async.{name}", **SERVICE_REQUESTS[name]}).encode()


def yaw_quaternion(theta: float) -> tuple[float, float, float, float]:
    """(x, y, z, w) of a rotation by ``theta`` radians about the z axis."""
    half = theta / 2.0
    return 0.0, 0.0, math.sin(half), math.cos(half)
