"""MCAP recordings read back (``galileo record --mcap``): topics, robots, their raw bytes.

A recording holds per robot ``/<robot>/raw`` (the bytes as they came off the link),
``/<robot>/status`` and ``/<robot>/events`` (docs/observability.md#mcap-recordings). The
messages are read in file order, one record after the other, so a file cut short (no
summary, a last chunk half written) is read up to its last whole chunk. Needs the
``mcap`` package (the extra ``[mcap]``).
"""

from __future__ import annotations

import struct
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any

from ..errors import InvalidArgument

__all__ = [
    "KINDS",
    "MCAP_MAGIC",
    "McapMessage",
    "is_mcap",
    "iter_mcap",
    "load_mcap_raw",
    "pick_robot",
    "topic",
]

#: The first bytes of every MCAP file (the format is told by content, not by file name).
MCAP_MAGIC = b"\x89MCAP0\r\n"
#: The channels of one robot, by the last part of their topic.
KINDS = ("raw", "status", "events")

#: (robot, kind, log time in ns, message bytes).
McapMessage = tuple[str, str, int, bytes]


def topic(robot: str, kind: str) -> str:
    """The topic of ``robot``'s channel ``kind`` (raw, status or events): ``/<robot>/<kind>``."""
    return f"/{robot}/{kind}"


def is_mcap(head: bytes) -> bool:
    """True when ``head`` (a file's first bytes) starts an MCAP file."""
    return head.startswith(MCAP_MAGIC)


def _reader_module() -> Any:
    try:
        from mcap import exceptions, records, stream_reader
    except ImportError:
        raise InvalidArgument(
            "reading an MCAP recording needs the mcap package: pip install 'galileo-async[mcap]'"
        ) from None
    return stream_reader, records, exceptions


def iter_mcap(stream: IO[bytes], name: str = "the recording") -> Iterator[McapMessage]:
    """Every message on a robot's topic, in file order; a cut-off tail ends the iteration.

    InvalidArgument when ``stream`` is not an MCAP file at all.
    """
    stream_reader, records, exceptions = _reader_module()
    if not is_mcap(stream.read(len(MCAP_MAGIC))):
        raise InvalidArgument(f"{name} is not an MCAP file")
    reader = stream_reader.StreamReader(stream, skip_magic=True)
    channels: dict[int, tuple[str, str] | None] = {}
    produced = False
    try:
        for record in reader.records:
            produced = True
            if isinstance(record, records.Channel):
                # /<robot>/<kind>: the kind is the last part; a fleet name may hold a '/'.
                head, _, kind = record.topic.rpartition("/")
                ours = head.startswith("/") and len(head) > 1 and kind in KINDS
                channels[record.id] = (head[1:], kind) if ours else None
            elif isinstance(record, records.Message):
                where = channels.get(record.channel_id)
                if where is not None:
                    yield where[0], where[1], record.log_time, bytes(record.data)
    except (exceptions.McapError, struct.error, ValueError, EOFError) as exc:
        if not produced:
            raise InvalidArgument(f"{name} is not a readable MCAP file: {exc}") from None
        return  # a file cut short: everything up to its last whole record


def _open(path: str | Path) -> IO[bytes]:
    try:
        return Path(path).open("rb")
    except OSError as exc:
        raise InvalidArgument(f"cannot read {path}: {exc.strerror or exc}") from None


def pick_robot(robots: list[str], robot: str | None, name: str) -> str:
    """``robot`` if the recording has it, or its only robot; InvalidArgument naming them."""
    present = ", ".join(sorted(robots)) or "none"
    if robot is not None:
        if robot not in robots:
            raise InvalidArgument(f"{name} has no robot {robot!r} (robots: {present})")
        return robot
    if len(robots) != 1:
        if not robots:
            raise InvalidArgument(f"{name} holds no robot's recording")
        raise InvalidArgument(f"{name} holds several robots: pick one of {present}")
    return robots[0]


def load_mcap_raw(path: str | Path, robot: str | None = None) -> list[tuple[float, bytes]]:
    """``robot``'s raw chunks as (seconds since the recording's first message, bytes).

    ``robot`` may be left out when the recording holds one robot's raw bytes. InvalidArgument
    when unreadable, ambiguous, or when the robot's link carried no raw bytes.
    """
    raw: dict[str, list[tuple[int, bytes]]] = {}
    robots: list[str] = []
    first: int | None = None
    with _open(path) as stream:
        for who, kind, log_time, data in iter_mcap(stream, str(path)):
            first = log_time if first is None else min(first, log_time)
            if who not in robots:
                robots.append(who)
            if kind == "raw":
                raw.setdefault(who, []).append((log_time, data))
    chosen = pick_robot(robots, robot, str(path))
    chunks = raw.get(chosen)
    if not chunks:
        raise InvalidArgument(
            f"{path}: robot {chosen!r} has no raw bytes (recorded over a link without them: "
            "udp://, http:// or ros://), so it cannot be replayed"
        )
    assert first is not None
    chunks.sort(key=lambda chunk: chunk[0])
    return [((log_time - first) / 1e9, data) for log_time, data in chunks]
