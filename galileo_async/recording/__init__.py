"""MCAP recordings of robots and fleets (the extra ``[mcap]``; docs/observability.md).

``McapRecorder`` records a Robot or a Fleet into one MCAP file without blocking the loop;
``read_recording`` reads one back. ``status_json``, ``status_schema``, ``event_log`` and
``LOG_SCHEMA`` are the JSON shapes a status and an event are recorded in, for any viewer
that wants the same (Foxglove's Log panel reads ``event_log``'s messages).
"""

from __future__ import annotations

from ..schemas import (
    LOG_SCHEMA,
    LOG_SCHEMA_NAME,
    STATUS_SCHEMA_NAME,
    event_log,
    log_level,
    status_json,
    status_schema,
)
from ..sim.mcap_read import MCAP_MAGIC, is_mcap, topic
from .reader import RecordedRobot, Recording, read_recording
from .recorder import DEFAULT_ROBOT_NAME, McapRecorder

__all__ = [
    "DEFAULT_ROBOT_NAME",
    "LOG_SCHEMA",
    "LOG_SCHEMA_NAME",
    "MCAP_MAGIC",
    "STATUS_SCHEMA_NAME",
    "McapRecorder",
    "RecordedRobot",
    "Recording",
    "event_log",
    "is_mcap",
    "log_level",
    "read_recording",
    "status_json",
    "status_schema",
    "topic",
]
