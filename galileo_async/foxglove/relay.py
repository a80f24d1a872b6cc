"""The public port: each connection relayed to the SDK's server, foxglove.websocket.v1 renamed.

The Foxglove SDK's server accepts only the subprotocol ``foxglove.sdk.v1``; Lichtblick and
the ws-protocol clients ask for ``foxglove.websocket.v1``. The two are the same protocol
under two names (docs/observability.md, "Foxglove live view"), so the relay renames the
subprotocol in the opening handshake, both ways, and then copies bytes untouched.
"""

from __future__ import annotations

import asyncio
import contextlib
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
_CHUNK = 65536
_PROTOCOL_LINE = re.compile(rb"(?im)^sec-websocket-protocol:[ \t]*([^\r\n]*)\r\n")


class Relay:
    """A TCP server on (host, port) relaying each connection to the SDK server on ``inner``."""

    def __init__(self, host: str, port: int, inner: int) -> None:
        self._host, self._port, self._inner = host, port, inner
        self._server: asyncio.Server | None = None
        self._tasks: set[asyncio.Task[None]] = set()

    @property
    def port(self) -> int:
        """The port clients connect to (the one bound, when 0 was asked)."""
        assert self._server is not None, "the relay is not started"
        return int(self._server.sockets[0].getsockname()[1])

    async def start(self) -> None:
        """Listen; OSError when the port is taken."""
        self._server = await asyncio.start_server(
            self._connection, self._host, self._port, reuse_address=True
        )

    async def close(self) -> None:
        """Stop listening and end every relayed connection; nothing is left running."""
        server, self._server = self._server, None
        if server is not None:
            server.close()
        tasks = list(self._tasks)
        for task in tasks:
            task.cancel()
        if tasks:
            await asyncio.wait(tasks)
        if server is not None:
            await server.wait_closed()

    async def _connection(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        task = asyncio.current_task()
        assert task is not None
        self._tasks.add(task)
        inner: asyncio.StreamWriter | None = None
        try:
            inner_reader, opened = await asyncio.wait_for(
                self._handshake(reader, writer), HANDSHAKE_TIMEOUT
            )
            inner = opened
            await _pipe_both(reader, writer, inner_reader, opened)
        except (OSError, asyncio.IncompleteReadError, asyncio.LimitOverrunError,
                asyncio.TimeoutError):  # fmt: skip
            _log.debug("foxglove relay: a connection ended", exc_info=True)
        finally:
            self._tasks.discard(task)
            for end in (writer, inner):
                if end is not None:
                    end.close()

    async def _handshake(
        self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter
    ) -> tuple[asyncio.StreamReader, asyncio.StreamWriter]:
        """Pass the upgrade request on and its answer back, the subprotocol renamed."""
        request, legacy = _rename_request(await reader.readuntil(b"\r\n\r\n"))
        inner_reader, inner = await asyncio.open_connection("127.0.0.1", self._inner)
        try:
            inner.write(request)
            answer = await inner_reader.readuntil(b"\r\n\r\n")
        except BaseException:
            inner.close()
            raise
        writer.write(_rename_answer(answer) if legacy else answer)
        return inner_reader, inner


def _rename_request(head: bytes) -> tuple[bytes, bool]:
    """The upgrade request with foxglove.websocket.v1 asked as foxglove.sdk.v1; was it asked?"""
    if len(head) > _MAX_HEAD:
        raise asyncio.LimitOverrunError("the handshake is too long", len(head))
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


async def _pipe_both(
    reader: asyncio.StreamReader,
    writer: asyncio.StreamWriter,
    inner_reader: asyncio.StreamReader,
    inner: asyncio.StreamWriter,
) -> None:
    """Copy both ways until either side ends; the other copy is then cancelled."""
    copies = {
        asyncio.ensure_future(_copy(reader, inner)),
        asyncio.ensure_future(_copy(inner_reader, writer)),
    }
    try:
        await asyncio.wait(copies, return_when=asyncio.FIRST_COMPLETED)
    finally:
        for copy in copies:
            copy.cancel()
        await asyncio.wait(copies)
        for copy in copies:
            if not copy.cancelled():
                with contextlib.suppress(OSError):
                    copy.result()


async def _copy(source: asyncio.StreamReader, sink: asyncio.StreamWriter) -> None:
    while chunk := await source.read(_CHUNK):
        sink.write(chunk)
        await sink.drain()
