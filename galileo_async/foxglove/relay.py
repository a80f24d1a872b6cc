"""The public port: each connection relayed to the SDK's server, foxglove.websocket.v1 renamed.

The Foxglove SDK's server accepts only the subprotocol ``foxglove.sdk.v1``; Lichtblick and
the ws-protocol clients ask for ``foxglove.websocket.v1``. The two are the same protocol
under two names (docs/observability.md, "Foxglove live view"), so the relay renames the
subprotocol in the opening handshake, both ways, and then copies bytes untouched.
"""

from __future__ import annotations

import asyncio
import logging
import re

__all__ = ["HANDSHAKE_TIMEOUT", "LEGACY_SUBPROTOCOL", "SDK_SUBPROTOCOL", "Relay"]

_log = logging.getLogger("galileo_async.foxglove")

#: The subprotocol the Foxglove SDK's server speaks (the current Foxglove app asks for it).
SDK_SUBPROTOCOL = "foxglove.sdk.v1"
#: The same protocol's older name (Lichtblick, @foxglove/ws-protocol).
LEGACY_SUBPROTOCOL = "foxglove.websocket.v1"
#: Seconds a client and the inner server have to finish their half of the opening handshake.
HANDSHAKE_TIMEOUT = 10.0
#: The largest HTTP head accepted (a browser's upgrade request is well under 2 KiB).
_MAX_HEAD = 16384
_PROTOCOL_LINE = re.compile(rb"(?im)^sec-websocket-protocol:[ \t]*([^\r\n]*)\r\n")


class Relay:
    """A TCP server on (host, port) relaying each connection to the SDK server on ``inner``."""

    def __init__(self, host: str, port: int, inner: int) -> None:
        self._host, self._port, self._inner = host, port, inner
        self._server: asyncio.Server | None = None
        self._pipes: set[_ClientSide] = set()

    @property
    def port(self) -> int:
        """The port clients connect to (the one bound, when 0 was asked)."""
        assert self._server is not None, "the relay is not started"
        return int(self._server.sockets[0].getsockname()[1])

    async def start(self) -> None:
        """Listen; OSError when the port is taken."""
        loop = asyncio.get_running_loop()
        self._server = await loop.create_server(
            lambda: _ClientSide(self._inner, self._pipes), self._host, self._port,
            reuse_address=True,
        )  # fmt: skip

    async def close(self) -> None:
        """Stop listening and end every relayed connection; nothing is left running."""
        server, self._server = self._server, None
        if server is not None:
            server.close()
        for pipe in list(self._pipes):
            pipe.end()
        if server is not None:
            await server.wait_closed()


class _Side(asyncio.Protocol):
    """One side of a relayed connection: once open, what it receives goes to the other."""

    transport: asyncio.Transport | None = None
    other: _Side | None = None

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        assert isinstance(transport, asyncio.Transport)
        self.transport = transport

    def pass_on(self, data: bytes) -> None:
        if self.other is not None and self.other.transport is not None:
            self.other.transport.write(data)

    # A side whose writes pile up holds the other side's reads back.
    def pause_writing(self) -> None:
        if self.other is not None and self.other.transport is not None:
            self.other.transport.pause_reading()

    def resume_writing(self) -> None:
        if self.other is not None and self.other.transport is not None:
            self.other.transport.resume_reading()

    def connection_lost(self, exc: Exception | None) -> None:
        self.transport = None
        if self.other is not None and self.other.transport is not None:
            self.other.transport.close()


class _ClientSide(_Side):
    """A viewer's connection: its upgrade request renamed, passed on, then bytes both ways."""

    def __init__(self, inner: int, pipes: set[_ClientSide]) -> None:
        self._inner, self._pipes = inner, pipes
        self._head = bytearray()
        self._opening: asyncio.Task[None] | None = None
        self._timer: asyncio.TimerHandle | None = None

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        super().connection_made(transport)
        self._pipes.add(self)
        self._timer = asyncio.get_running_loop().call_later(HANDSHAKE_TIMEOUT, self.end)

    def data_received(self, data: bytes) -> None:
        if self.other is not None and self.other.transport is not None and self._timer is None:
            self.pass_on(data)
            return
        if self._opening is not None:  # bytes after the request, before the answer
            self._head += data
            return
        self._head += data
        end = self._head.find(b"\r\n\r\n")
        if end < 0:
            if len(self._head) > _MAX_HEAD:
                self.end()
            return
        request, rest = bytes(self._head[: end + 4]), bytes(self._head[end + 4 :])
        self._head = bytearray(rest)
        renamed, legacy = _rename_request(request)
        assert self.transport is not None
        self.transport.pause_reading()
        self._opening = asyncio.ensure_future(self._open(renamed, legacy))

    async def _open(self, request: bytes, legacy: bool) -> None:
        loop = asyncio.get_running_loop()
        try:
            _, inner = await loop.create_connection(
                lambda: _InnerSide(self, legacy), "127.0.0.1", self._inner
            )
        except OSError:
            _log.debug("foxglove relay: the inner server refused", exc_info=True)
            self.end()
            return
        self.other = inner
        assert inner.transport is not None
        inner.transport.write(request + bytes(self._head))
        self._head.clear()

    def answered(self) -> None:
        """The inner server answered the upgrade: from now on, bytes both ways."""
        if self._timer is not None:
            self._timer.cancel()
            self._timer = None
        if self.transport is not None:
            self.transport.resume_reading()

    def end(self) -> None:
        """Close both sides and forget the connection."""
        if self._timer is not None:
            self._timer.cancel()
            self._timer = None
        if self._opening is not None and not self._opening.done():
            self._opening.cancel()
        for side in (self, self.other):
            if side is not None and side.transport is not None:
                side.transport.abort()
        self._pipes.discard(self)

    def connection_lost(self, exc: Exception | None) -> None:
        super().connection_lost(exc)
        self.end()


class _InnerSide(_Side):
    """The connection to the SDK's server: its answer renamed back, then bytes both ways."""

    def __init__(self, client: _ClientSide, legacy: bool) -> None:
        self.other = client
        self._client, self._legacy = client, legacy
        self._head: bytearray | None = bytearray()

    def data_received(self, data: bytes) -> None:
        if self._head is None:
            self.pass_on(data)
            return
        self._head += data
        end = self._head.find(b"\r\n\r\n")
        if end < 0:
            if len(self._head) > _MAX_HEAD:
                self._client.end()
            return
        answer, rest = bytes(self._head[: end + 4]), bytes(self._head[end + 4 :])
        self._head = None
        self.pass_on((_rename_answer(answer) if self._legacy else answer) + rest)
        self._client.answered()


def _rename_request(head: bytes) -> tuple[bytes, bool]:
    """The upgrade request with foxglove.websocket.v1 asked as foxglove.sdk.v1; was it asked?"""
    found = _PROTOCOL_LINE.search(head)
    if found is None:
        return head, False
    offered = [name.strip() for name in found.group(1).decode("latin-1").split(",")]
    if SDK_SUBPROTOCOL in offered or LEGACY_SUBPROTOCOL not in offered:
        return head, False
    line = f"Sec-WebSocket-Protocol: {SDK_SUBPROTOCOL}\r\n".encode()
    return head[: found.start()] + line + head[found.end() :], True


def _rename_answer(head: bytes) -> bytes:
    """The server's answer with the subprotocol the client asked for."""
    line = f"Sec-WebSocket-Protocol: {LEGACY_SUBPROTOCOL}\r\n".encode()
    return _PROTOCOL_LINE.sub(line.replace(b"\\", b"\\\\"), head, count=1)
