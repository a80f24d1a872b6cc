"""read_recording(): an MCAP recording's robots, with their raw bytes, statuses and events."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

from ..errors import InvalidArgument
from ..sim.mcap_read import iter_mcap, pick_robot

__all__ = ["RecordedRobot", "Recording", "read_recording"]


@dataclass
class RecordedRobot:
    """One robot of a recording; times are seconds since the recording's first message."""

    name: str
    #: (seconds, bytes) of each read, when the link carried raw bytes; else empty.
    raw: list[tuple[float, bytes]] = field(default_factory=list)
    #: (seconds, status as JSON values: ``status_json``'s shape).
    statuses: list[tuple[float, dict[str, Any]]] = field(default_factory=list)
    #: (seconds, foxglove.Log message: ``event_log``'s shape).
    events: list[tuple[float, dict[str, Any]]] = field(default_factory=list)


@dataclass
class Recording:
    """The robots of a recording, in the order they first appear."""

    robots: dict[str, RecordedRobot]
    #: The first message's log time (ns since the epoch); None for an empty recording.
    start_ns: int | None

    def robot(self, name: str | None = None) -> RecordedRobot:
        """Robot ``name``, or the only one; InvalidArgument naming the robots present."""
        return self.robots[pick_robot(list(self.robots), name, "the recording")]


def read_recording(source: str | Path | IO[bytes]) -> Recording:
    """Read an MCAP recording (a path or a binary stream), up to its last whole chunk.

    InvalidArgument when it cannot be read or is no MCAP file.
    """
    if isinstance(source, (str, Path)):
        try:
            with Path(source).open("rb") as stream:
                return _read(stream, str(source))
        except OSError as exc:
            raise InvalidArgument(f"cannot read {source}: {exc.strerror or exc}") from None
    return _read(source, "the recording")


def _read(stream: IO[bytes], name: str) -> Recording:
    messages = list(iter_mcap(stream, name))
    start = min((log_time for _, _, log_time, _ in messages), default=None)
    robots: dict[str, RecordedRobot] = {}
    for who, kind, log_time, data in sorted(messages, key=lambda message: message[2]):
        robot = robots.get(who)
        if robot is None:
            robot = robots[who] = RecordedRobot(who)
        assert start is not None
        seconds = (log_time - start) / 1e9
        if kind == "raw":
            robot.raw.append((seconds, data))
            continue
        try:
            value = json.loads(data)
        except ValueError:
            raise InvalidArgument(f"{name}: a {kind} message of {who} is not JSON") from None
        (robot.statuses if kind == "status" else robot.events).append((seconds, value))
    return Recording(robots, start)
