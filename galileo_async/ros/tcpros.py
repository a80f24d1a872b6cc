"""TCPROS: connection headers, length-prefixed framing, a topic publisher and a subscriber."""

from __future__ import annotations

import asyncio
import contextlib
import socket
import struct
from collections.abc import Callable

from ..errors import GalileoConnectionError
from ..transports.connectors import set_keepalive
from ._server import close_server

__all__ = [
    "MAX_FRAME",
    "MAX_WRITE_BUFFER",
    "Framer",
    "TcprosError",
    "TcprosPublisher",
    "decode_header",
    "encode_header",
    "frame",
    "set_keepalive",
    "subscribe",
]

#: Largest header or message accepted from a peer; a status message is about 100 bytes.
MAX_FRAME = 1 << 20
#: A subscriber whose socket buffer grows past this is disconnected rather than queued for.
MAX_WRITE_BUFFER = 1 << 20

_U32 = struct.Struct("<I")


class TcprosError(GalileoConnectionError):
    """A TCPROS peer refused the connection, sent a bad header or could not be reached."""


def frame(data: bytes) -> bytes:
    """Prefix data with its little-endian uint32 length."""
    return _U32.pack(len(data)) + data


def encode_header(fields: dict[str, str]) -> bytes:
    """A connection header: ``key=value`` entries, each length-prefixed, framed."""
    return frame(b"".join(frame(f"{key}={value}".encode()) for key, value in fields.items()))


def decode_header(data: bytes) -> dict[str, str]:
    """Parse the body of a connection header (without its outer length)."""
    fields: dict[str, str] = {}
    offset = 0
    while offset < len(data):
        if offset + 4 > len(data):
            raise TcprosError("truncated connection header")
        (size,) = _U32.unpack_from(data, offset)
        entry = data[offset + 4 : offset + 4 + size]
        if len(entry) != size:
            raise TcprosError("truncated connection header entry")
        key, sep, value = entry.decode("utf-8", "replace").partition("=")
        if not sep:
            raise TcprosError(f"connection header entry without '=': {key!r}")
        fields[key] = value
        offset += 4 + size
    return fields


class Framer:
    """Split a byte stream into length-prefixed frames (bounded by MAX_FRAME)."""

    def __init__(self) -> None:
        self._buffer = bytearray()

    def feed(self, data: bytes) -> list[bytes]:
        """Append data; return every complete frame body; raise TcprosError when oversized."""
        self._buffer += data
        frames: list[bytes] = []
        buffer = self._buffer
        offset = 0
        while len(buffer) - offset >= 4:
            (size,) = _U32.unpack_from(buffer, offset)
            if size > MAX_FRAME:
                raise TcprosError(f"frame of {size} bytes exceeds {MAX_FRAME}")
            if len(buffer) - offset - 4 < size:
                break
            frames.append(bytes(buffer[offset + 4 : offset + 4 + size]))
            offset += 4 + size
        del buffer[:offset]
        return frames


class _PublisherConnection(asyncio.Protocol):
    """One subscriber of a TcprosPublisher: handshake, then write-only."""

    def __init__(self, publisher: TcprosPublisher) -> None:
        self._publisher = publisher
        self._framer = Framer()
        self.transport: asyncio.Transport | None = None
        self.ready = False

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        assert isinstance(transport, asyncio.Transport)
        self.transport = transport
        set_keepalive(transport)

    def data_received(self, data: bytes) -> None:
        if self.ready or self.transport is None:
            return  # subscribers send nothing after their header
        try:
            frames = self._framer.feed(data)
            if not frames:
                return
            header = decode_header(frames[0])
        except TcprosError:
            self.transport.abort()
            return
        error = self._publisher.check(header)
        if error:
            self.transport.write(encode_header({"error": error}))
            self.transport.close()
            return
        self.transport.write(encode_header(self._publisher.response_header()))
        if header.get("tcp_nodelay") == "1":
            with contextlib.suppress(OSError):
                sock = self.transport.get_extra_info("socket")
                if sock is not None:
                    sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.ready = True
        self._publisher.added(self)

    def connection_lost(self, exc: Exception | None) -> None:
        self._publisher.removed(self)
        self.transport = None


class TcprosPublisher:
    """Serve one topic over TCPROS: answer subscribers' headers, write each message to all."""

    def __init__(
        self, *, topic: str, msg_type: str, md5sum: str, definition: str, caller_id: str
    ) -> None:
        self.topic = topic
        self.msg_type = msg_type
        self.md5sum = md5sum
        self.definition = definition
        self.caller_id = caller_id
        self.port: int | None = None
        self._server: asyncio.Server | None = None
        self._connections: set[_PublisherConnection] = set()
        self._changed = asyncio.Event()
        self.on_change: Callable[[int], None] | None = None

    @property
    def subscriber_count(self) -> int:
        """How many subscribers completed the handshake and are still connected."""
        return len(self._connections)

    async def start(self, host: str, port: int = 0) -> int:
        """Listen on host:port (0 picks a free port); return the port."""
        loop = asyncio.get_running_loop()
        try:
            self._server = await loop.create_server(lambda: _PublisherConnection(self), host, port)
        except OSError as exc:
            raise TcprosError(f"cannot listen on {host}:{port}: {exc}") from exc
        self.port = self._server.sockets[0].getsockname()[1]
        return self.port

    def check(self, header: dict[str, str]) -> str | None:
        """Why a subscriber's header is refused, or None to accept it."""
        if header.get("topic") != self.topic:
            return f"topic {header.get('topic')!r} is not served here ({self.topic})"
        if header.get("md5sum") not in ("*", self.md5sum):
            return f"md5sum mismatch for {self.msg_type}: {header.get('md5sum')} != {self.md5sum}"
        return None

    def response_header(self) -> dict[str, str]:
        """The header sent to an accepted subscriber."""
        return {
            "callerid": self.caller_id,
            "md5sum": self.md5sum,
            "type": self.msg_type,
            "message_definition": self.definition,
            "latching": "0",
            "topic": self.topic,
        }

    def added(self, connection: _PublisherConnection) -> None:
        """A subscriber finished its handshake."""
        self._connections.add(connection)
        self._notify()

    def removed(self, connection: _PublisherConnection) -> None:
        """A subscriber went away."""
        if connection in self._connections:
            self._connections.discard(connection)
            self._notify()

    def _notify(self) -> None:
        self._changed.set()
        self._changed = asyncio.Event()
        if self.on_change is not None:
            self.on_change(len(self._connections))

    async def wait_for_subscriber(self, timeout: float) -> bool:
        """Wait until at least one subscriber is connected; False on timeout."""
        loop = asyncio.get_running_loop()
        deadline = loop.time() + timeout
        while not self._connections:
            remaining = deadline - loop.time()
            if remaining <= 0:
                return False
            with contextlib.suppress(asyncio.TimeoutError):
                await asyncio.wait_for(self._changed.wait(), remaining)
        return True

    def publish(self, message: bytes) -> int:
        """Write one serialised message to every subscriber; return how many got it."""
        data = frame(message)
        sent = 0
        for connection in list(self._connections):
            transport = connection.transport
            if transport is None or transport.is_closing():
                continue
            if transport.get_write_buffer_size() > MAX_WRITE_BUFFER:
                transport.abort()
                continue
            transport.write(data)
            sent += 1
        return sent

    def stop(self) -> None:
        """Stop listening and drop every subscriber, at once (close() also waits)."""
        for connection in list(self._connections):
            if connection.transport is not None:
                connection.transport.abort()
        self._connections.clear()
        if self._server is not None:
            self._server.close()

    async def close(self) -> None:
        """Stop listening, drop every subscriber and wait (bounded) for the server to close."""
        self.stop()
        server, self._server = self._server, None
        await close_server(server)


class _SubscriberProtocol(asyncio.Protocol):
    """Client side of a subscription: send our header, await theirs, then deliver messages.

    ``on_handshake`` takes the publisher's header before any message is delivered, in the
    same call, so a message that arrives in the same read as the header is not lost to a
    receiver that is set up from the header (the status decoder is).
    """

    def __init__(
        self,
        header: dict[str, str],
        on_message: Callable[[bytes], None],
        on_closed: Callable[[Exception | None], None],
        on_handshake: Callable[[dict[str, str]], None] | None = None,
    ) -> None:
        self._header = header
        self._on_message = on_message
        self._on_closed = on_closed
        self._on_handshake = on_handshake
        self._framer = Framer()
        self.handshake: asyncio.Future[dict[str, str]] = asyncio.get_running_loop().create_future()
        self.transport: asyncio.Transport | None = None
        self._established = False

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        assert isinstance(transport, asyncio.Transport)
        self.transport = transport
        set_keepalive(transport)
        transport.write(encode_header(self._header))

    def data_received(self, data: bytes) -> None:
        try:
            frames = self._framer.feed(data)
            if frames and not self.handshake.done():
                header = decode_header(frames.pop(0))
                if "error" in header:
                    raise TcprosError(f"publisher refused: {header['error']}")
                if self._on_handshake is not None:
                    self._on_handshake(header)
                self.handshake.set_result(header)
                self._established = True
        except (TcprosError, ValueError) as exc:
            if not self.handshake.done():
                self.handshake.set_exception(exc)
            if self.transport is not None:
                self.transport.abort()
            return
        if self._established:
            for message in frames:
                self._on_message(message)

    def connection_lost(self, exc: Exception | None) -> None:
        if not self.handshake.done():
            self.handshake.set_exception(
                TcprosError(f"publisher closed during the handshake: {exc}")
            )
            self.handshake.exception()  # retrieved: nobody may be awaiting any more
        if self._established:
            self._on_closed(exc)


async def subscribe(
    host: str,
    port: int,
    header: dict[str, str],
    on_message: Callable[[bytes], None],
    on_closed: Callable[[Exception | None], None],
    *,
    timeout: float,
    on_handshake: Callable[[dict[str, str]], None] | None = None,
) -> tuple[asyncio.Transport, dict[str, str]]:
    """Connect to a publisher, exchange headers; then every message goes to on_message.

    ``on_handshake(header)`` runs before the first message is delivered; a ValueError it
    raises fails the subscription with that error.
    """
    loop = asyncio.get_running_loop()
    transport: asyncio.BaseTransport | None = None

    async def handshake() -> dict[str, str]:
        nonlocal transport
        transport, protocol = await loop.create_connection(
            lambda: _SubscriberProtocol(header, on_message, on_closed, on_handshake), host, port
        )
        return await protocol.handshake

    try:
        reply = await asyncio.wait_for(handshake(), timeout)
    except BaseException as exc:
        if isinstance(transport, asyncio.Transport):
            transport.abort()
        if isinstance(exc, asyncio.TimeoutError):
            raise TcprosError(
                f"cannot subscribe at {host}:{port}: no TCPROS handshake within {timeout:.2f} s"
            ) from exc
        if isinstance(exc, OSError) and not isinstance(exc, TcprosError):
            raise TcprosError(f"cannot subscribe at {host}:{port}: {exc!r}") from exc
        raise
    assert isinstance(transport, asyncio.Transport)
    return transport, reply
