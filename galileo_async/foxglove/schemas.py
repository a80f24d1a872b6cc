"""What the Foxglove channels carry, without the SDK: JSON schemas, the status and link as JSON,
events as log lines, and the services' request schemas (docs/observability.md)."""

from __future__ import annotations

import json
import math
from functools import cache
from typing import TYPE_CHECKING, Any

from ..events import (
    AbandonedGoalCancelled,
    ConnectionLostEvent,
    Event,
    GoalAbortedEvent,
    GoalCancelledEvent,
    GoalRejectedEvent,
    GoalStalledEvent,
    LinkStaleEvent,
    VisualLost,
)
from ..models import GalileoStatus

if TYPE_CHECKING:
    from ..robot import MapImage, Robot

__all__ = [
    "ERROR",
    "INFO",
    "LINK_SCHEMA_NAME",
    "MAP_INFO_SCHEMA_NAME",
    "SERVICE_REQUESTS",
    "STATUS_SCHEMA_NAME",
    "WARNING",
    "event_level",
    "event_text",
    "link_json",
    "link_schema",
    "map_info_json",
    "map_info_schema",
    "service_schema",
    "status_json",
    "status_schema",
    "yaw_quaternion",
]

#: The schema name of the status channels (JSON Schema of GalileoStatus).
STATUS_SCHEMA_NAME = "galileo_async.GalileoStatus"
#: The schema name of the link channels.
LINK_SCHEMA_NAME = "galileo_async.LinkStats"
#: The schema name of the map_info channels.
MAP_INFO_SCHEMA_NAME = "galileo_async.MapInfo"

#: foxglove.Log levels (the values of foxglove.messages.LogLevel), as plain numbers.
INFO, WARNING, ERROR = 2, 3, 4

#: Events an operator should look at: a goal that ended short, a link in trouble, the
#: robot lost; every other event is INFO.
_WARNINGS: tuple[type[Event], ...] = (
    GoalAbortedEvent, GoalCancelledEvent, AbandonedGoalCancelled, GoalStalledEvent,
    LinkStaleEvent, VisualLost,
)  # fmt: skip
_ERRORS: tuple[type[Event], ...] = (GoalRejectedEvent, ConnectionLostEvent)

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
def status_schema() -> bytes:
    """GalileoStatus's JSON Schema, as the status channels carry it (built once)."""
    schema = GalileoStatus.model_json_schema()
    schema["title"] = STATUS_SCHEMA_NAME
    return json.dumps(schema).encode()


def status_json(status: GalileoStatus) -> bytes:
    """One status message: the status's JSON dump (its schema is status_schema())."""
    return status.model_dump_json().encode()


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


def event_level(event: Event) -> int:
    """The foxglove.Log level of ``event``: ERROR, WARNING or INFO."""
    if isinstance(event, _ERRORS):
        return ERROR
    if isinstance(event, _WARNINGS):
        return WARNING
    return INFO


def event_text(event: Event) -> str:
    """The log line of ``event``: its str() (``GoalReached(target_id=3, distance=0.05)``)."""
    return str(event)


def yaw_quaternion(theta: float) -> tuple[float, float, float, float]:
    """(x, y, z, w) of a rotation by ``theta`` radians about the z axis."""
    half = theta / 2.0
    return 0.0, 0.0, math.sin(half), math.cos(half)
