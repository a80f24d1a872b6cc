"""Replay: a ``galileo record`` capture served as a robot, its bytes at their recorded pace.

Capture format (written by ``galileo record``): the 18-byte magic ``GALILEO-CAPTURE 1\\n``,
then one record per chunk received: a little-endian float64 (seconds since the recording
started), a little-endian uint32 byte count, and that many bytes exactly as they came off
the link. Plain raw dumps (no magic) carry no timing and cannot be replayed. An MCAP recording
(``galileo record --mcap``, told by its own magic) is replayed from a robot's raw channel
(mcap_read.py).
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import struct
from collections.abc import Iterator
from pathlib import Path
from typing import IO

from ..errors import InvalidArgument
from ..protocol import CommandDecoder
from .mcap_read import MCAP_MAGIC, is_mcap, load_mcap_raw

__all__ = ["MAGIC", "RECORD", "ReplayConnection", "iter_capture", "load_capture"]

#: First bytes of a recording made by ``galileo record``.
MAGIC = b"GALILEO-CAPTURE 1\n"
#: Per-chunk header of a recording: seconds since start (float64), byte count (uint32).
RECORD = struct.Struct("<dI")
_READ_SIZE = 65536

_log = logging.getLogger(__name__)


def iter_capture(stream: IO[bytes]) -> Iterator[tuple[float | None, bytes]]:
    """Yield (seconds or None, bytes) chunks from a recording or a raw dump."""
    head = stream.read(len(MAGIC))
    if head != MAGIC:
        if head:
            yield None, head
        while chunk := stream.read(_READ_SIZE):
            yield None, chunk
        return
    while True:
        prefix = stream.read(RECORD.size)
        if len(prefix) < RECORD.size:
            return  # end of file (a cut-off record header is ignored)
        seconds, size = RECORD.unpack(prefix)
        data = stream.read(size)
        if data:
            yield seconds, data
        if len(data) < size:
            return


def load_capture(path: str | Path, robot: str | None = None) -> list[tuple[float, bytes]]:
    """The timed chunks of a recording; InvalidArgument when unreadable, raw or empty.

    An MCAP recording (told by its first bytes) gives ``robot``'s raw channel; ``robot``
    may be left out when it holds one robot.
    """
    try:
        with Path(path).open("rb") as stream:
            mcap = is_mcap(stream.read(len(MCAP_MAGIC)))
            stream.seek(0)
            chunks = [] if mcap else list(iter_capture(stream))
    except OSError as exc:
        raise InvalidArgument(f"cannot read the capture {path}: {exc.strerror or exc}") from None
    if mcap:
        return load_mcap_raw(path, robot)
    if robot is not None:
        raise InvalidArgument(
            f"robot={robot} picks a robot of an MCAP recording: {path} is not one"
        )
    timed = [(seconds, data) for seconds, data in chunks if seconds is not None]
    if len(timed) != len(chunks):
        raise InvalidArgument(
            f"{path} is a raw dump without timing: record it without --raw to replay it"
        )
    if not timed:
        raise InvalidArgument(f"{path} holds no recorded bytes")
    return timed


class ReplayConnection(asyncio.Protocol):
    """One host connection: the capture's bytes from its start; commands received are logged."""

    def __init__(self, chunks: list[tuple[float, bytes]], speed: float, name: str) -> None:
        self._chunks = chunks
        self._speed = speed
        self._name = name
        self._decoder = CommandDecoder()
        self._task: asyncio.Task[None] | None = None
        #: Commands received from the host, in order (also logged at INFO).
        self.commands: list[object] = []

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        """Start sending the capture from its first chunk."""
        assert isinstance(transport, asyncio.WriteTransport)
        self._task = asyncio.ensure_future(self._play(transport))

    async def _play(self, transport: asyncio.WriteTransport) -> None:
        loop = asyncio.get_running_loop()
        began = loop.time()
        first = self._chunks[0][0]
        for seconds, data in self._chunks:
            delay = began + (seconds - first) / self._speed - loop.time()
            if delay > 0:
                await asyncio.sleep(delay)
            if transport.is_closing():
                return
            transport.write(data)
        _log.info("%s: the capture ended: closing the connection", self._name)
        transport.close()

    def data_received(self, data: bytes) -> None:
        """Commands from the host: decoded and logged, never acted on."""
        for command in self._decoder.feed(data):
            self.commands.append(command)
            _log.info("%s: command %r", self._name, command)

    def connection_lost(self, exc: Exception | None) -> None:
        """Stop playing."""
        if self._task is not None:
            self._task.cancel()

    def close(self) -> None:
        """Stop playing (the host sees the connection drop once its transport closes)."""
        if self._task is not None:
            self._task.cancel()

    async def wait_closed(self) -> None:
        """Wait for the playing task to end."""
        if self._task is not None:
            with contextlib.suppress(asyncio.CancelledError):
                await self._task
