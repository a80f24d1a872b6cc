"""Open a bare byte stream to a URL (no decoding), for ``galileo record``."""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import AsyncIterator

from ..links import byte_connector

__all__ = ["RECORD_QUEUE_CHUNKS", "ChunkQueue", "open_raw"]

#: Most received chunks waiting for the file writer; beyond it chunks are dropped and counted.
RECORD_QUEUE_CHUNKS = 4096


class ChunkQueue:
    """Received chunks as (loop time, bytes) for one writer; bounded, drops counted; then None."""

    def __init__(self, limit: int = RECORD_QUEUE_CHUNKS) -> None:
        self._queue: asyncio.Queue[tuple[float, bytes] | None] = asyncio.Queue(limit)
        self.ended = False
        #: Why the link closed, when the transport said (an error's text), else None.
        self.reason: str | None = None
        self.dropped_chunks = 0
        self.dropped_bytes = 0

    def put(self, when: float, data: bytes) -> None:
        """Queue a chunk, or count it as dropped when the writer is ``limit`` chunks behind."""
        try:
            self._queue.put_nowait((when, data))
        except asyncio.QueueFull:
            self.dropped_chunks += 1
            self.dropped_bytes += len(data)

    def end(self, reason: str | None = None) -> None:
        """The link closed (for ``reason``): get() returns None once the queued chunks are read."""
        self.ended = True
        self.reason = reason
        with contextlib.suppress(asyncio.QueueFull):
            self._queue.put_nowait(None)  # wakes a waiting get(); a full queue needs no wake

    async def get(self) -> tuple[float, bytes] | None:
        """The next chunk, or None after the last one once the link closed."""
        if self.ended and self._queue.empty():
            return None
        return await self._queue.get()


class _Tap(asyncio.Protocol):
    """Puts every received chunk, stamped with the loop time, on a queue."""

    def __init__(self, chunks: ChunkQueue) -> None:
        self._chunks = chunks
        self._loop = asyncio.get_running_loop()

    def data_received(self, data: bytes) -> None:
        self._chunks.put(self._loop.time(), bytes(data))

    def eof_received(self) -> bool | None:
        return None  # let the transport close

    def connection_lost(self, exc: Exception | None) -> None:
        self._chunks.end(None if exc is None else str(exc) or type(exc).__name__)


@contextlib.asynccontextmanager
async def open_raw(url: str, chunks: ChunkQueue) -> AsyncIterator[float]:
    """Stream the bytes arriving from ``url`` into ``chunks``; yield the start (loop time)."""
    loop = asyncio.get_running_loop()
    connector, simulator = byte_connector(url)
    try:
        started = loop.time()
        transport, _protocol = await connector(loop, lambda: _Tap(chunks))
        try:
            yield started
        finally:
            transport.close()
    finally:
        if simulator is not None:
            await simulator.close()
