"""The JSON a viewer gets of a status and an event, and their JSON schemas (no I/O).

``status_json`` is a status as ``GalileoStatus.model_dump(mode="json")`` gives it (enums
as their wire integers, the layout as its name), built without pydantic: it runs for every
frame recorded. ``STATUS_SCHEMA`` is the status model's JSON schema. ``event_log`` is an
event as a ``foxglove.Log`` message (so Foxglove's and Lichtblick's Log panel shows it),
with the event's name and fields kept in ``event``; ``LOG_SCHEMA`` its schema. MCAP
recordings (galileo_async.recording) and the Foxglove view (galileo_async.foxglove) both
carry these.
"""

from __future__ import annotations

import dataclasses
import enum
import functools
from typing import Any

from .events import (
    AbandonedGoalCancelled,
    ConnectionLostEvent,
    Event,
    GoalAbortedEvent,
    GoalRejectedEvent,
    GoalStalledEvent,
    LinkStaleEvent,
    VisualLost,
)
from .models import STATUS_FIELDS, GalileoStatus

__all__ = [
    "LOG_LEVELS",
    "LOG_SCHEMA",
    "LOG_SCHEMA_NAME",
    "STATUS_SCHEMA_NAME",
    "event_log",
    "event_message",
    "log_level",
    "status_json",
    "status_schema",
]

#: The status channel's schema name (encoding ``jsonschema``).
STATUS_SCHEMA_NAME = "galileo_async.GalileoStatus"
#: The events channel's schema name: Foxglove's well-known log message.
LOG_SCHEMA_NAME = "foxglove.Log"
#: foxglove.Log levels.
LOG_LEVELS = {"UNKNOWN": 0, "DEBUG": 1, "INFO": 2, "WARNING": 3, "ERROR": 4, "FATAL": 5}
_WARNINGS = (
    GoalAbortedEvent, GoalRejectedEvent, GoalStalledEvent, AbandonedGoalCancelled,
    LinkStaleEvent, VisualLost,
)  # fmt: skip
_ERRORS = (ConnectionLostEvent,)

#: foxglove.Log's JSON schema, with the optional ``event`` this project adds.
LOG_SCHEMA: dict[str, Any] = {
    "title": "foxglove.Log",
    "description": "A log message",
    "$comment": "foxglove.Log with the event's name and fields in 'event'",
    "type": "object",
    "properties": {
        "timestamp": {
            "type": "object",
            "title": "time",
            "properties": {
                "sec": {"type": "integer", "minimum": 0},
                "nsec": {"type": "integer", "minimum": 0, "maximum": 999999999},
            },
            "description": "Timestamp of log message",
        },
        "level": {
            "title": "foxglove.LogLevel",
            "description": "Log level",
            "oneOf": [{"title": k, "const": v} for k, v in LOG_LEVELS.items()],
        },
        "message": {"type": "string", "description": "Log message"},
        "name": {"type": "string", "description": "Process or node name"},
        "file": {"type": "string", "description": "Filename"},
        "line": {"type": "integer", "minimum": 0, "description": "Line number in the file"},
        "event": {
            "type": "object",
            "description": "The event: its name ('event') and its fields",
            "properties": {"event": {"type": "string"}},
        },
    },
}


@functools.cache
def status_schema() -> dict[str, Any]:
    """The JSON schema of ``status_json``'s output (the status model's)."""
    schema = dict(GalileoStatus.model_json_schema())
    schema["title"] = STATUS_SCHEMA_NAME
    return schema


def status_json(status: GalileoStatus) -> dict[str, Any]:
    """``status`` as JSON values: equal to ``status.model_dump(mode="json")``, faster."""
    values: dict[str, Any] = {"layout": status.layout.value}
    for name in STATUS_FIELDS:
        value = getattr(status, name)
        values[name] = int(value) if isinstance(value, enum.IntEnum) else value
    return values


def log_level(event: Event) -> int:
    """The foxglove.Log level of ``event``: WARNING for a failed or abandoned goal, a stale
    link or lost tracking, ERROR for a lost connection, INFO otherwise (a user's cancel too)."""
    if isinstance(event, _ERRORS):
        return LOG_LEVELS["ERROR"]
    if isinstance(event, _WARNINGS):
        return LOG_LEVELS["WARNING"]
    return LOG_LEVELS["INFO"]


def _event_fields(event: Event) -> dict[str, Any]:
    values: dict[str, Any] = {"event": event.name}
    for item in dataclasses.fields(event):
        if item.name == "status":
            continue
        value = getattr(event, item.name)
        if isinstance(value, enum.Enum):
            value = value.name.lower()
        elif not isinstance(value, (int, float, str, bool, type(None))):
            value = str(value)
        values[item.name] = value
    return values


def event_message(event: Event) -> str:
    """The log line of ``event``: its name and fields (``GoalReached target_id=3 …``)."""
    return _message(_event_fields(event))


def _message(fields: dict[str, Any]) -> str:
    details = " ".join(f"{key}={value}" for key, value in fields.items() if key != "event")
    return f"{fields['event']} {details}".strip()


def event_log(event: Event, when_ns: int, robot: str) -> dict[str, Any]:
    """``event`` as a foxglove.Log message of ``robot`` at ``when_ns`` (ns since the epoch)."""
    fields = _event_fields(event)
    return {
        "timestamp": {"sec": when_ns // 1_000_000_000, "nsec": when_ns % 1_000_000_000},
        "level": log_level(event),
        "message": _message(fields),
        "name": robot,
        "file": "",
        "line": 0,
        "event": fields,
    }
