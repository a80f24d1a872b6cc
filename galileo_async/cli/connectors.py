"""Open a bare byte stream to a URL (no decoding), for ``galileo record``."""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import AsyncIterator
from urllib.parse import urlsplit

from ..link.connectors import Connector, parse_socket_url, serial_connector, socket_connector

__all__ = ["ChunkQueue", "open_raw"]

#: Received chunks as (loop time, bytes); None once the link closed.
ChunkQueue = asyncio.Queue[tuple[float, bytes] | None]


class _Tap(asyncio.Protocol):
    """Puts every received chunk, stamped with the loop time, on a queue."""

    def __init__(self, chunks: ChunkQueue) -> None:
        self._chunks = chunks
        self._loop = asyncio.get_running_loop()

    def data_received(self, data: bytes) -> None:
        self._chunks.put_nowait((self._loop.time(), bytes(data)))

    def eof_received(self) -> bool | None:
        return None  # let the transport close

    def connection_lost(self, exc: Exception | None) -> None:
        self._chunks.put_nowait(None)


@contextlib.asynccontextmanager
async def open_raw(url: str, chunks: ChunkQueue) -> AsyncIterator[float]:
    """Stream the bytes arriving from ``url`` into ``chunks``; yield the start (loop time)."""
    loop = asyncio.get_running_loop()
    simulator = None
    scheme = urlsplit(url).scheme.lower()
    connector: Connector
    if scheme == "sim":
        from ..sim import Simulator

        simulator = Simulator.from_url(url)
        connector = simulator.connector()
    elif scheme == "socket":
        host, port = parse_socket_url(url)
        connector = socket_connector(host, port)
    else:
        connector = serial_connector(url)
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
