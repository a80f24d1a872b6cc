"""SocketTransport: the lean TCP transport of socket:// links, over 127.0.0.1."""

from __future__ import annotations

import asyncio
import socket
import struct
from collections.abc import AsyncIterator, Callable
from typing import Any

import pytest

from galileo_async.errors import GalileoConnectionError
from galileo_async.link.connectors import socket_connector
from galileo_async.link.sockets import SocketTransport, open_socket

STEP = 2.0  # upper bound for anything that should happen promptly
BIG = 4 << 20  # more than a loopback socket takes without its peer reading


class Peer:
    """The server side of one connection."""

    def __init__(self) -> None:
        self.connected = asyncio.Event()
        self.reader: asyncio.StreamReader | None = None
        self.writer: asyncio.StreamWriter | None = None

    async def accept(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        self.reader, self.writer = reader, writer
        self.connected.set()

    async def ready(self) -> tuple[asyncio.StreamReader, asyncio.StreamWriter]:
        await asyncio.wait_for(self.connected.wait(), STEP)
        assert self.reader is not None
        assert self.writer is not None
        return self.reader, self.writer


@pytest.fixture
async def peer() -> AsyncIterator[tuple[Peer, int]]:
    side = Peer()
    server = await asyncio.start_server(side.accept, "127.0.0.1", 0)
    port = server.sockets[0].getsockname()[1]
    yield side, port
    if side.writer is not None:
        side.writer.close()
    server.close()
    await server.wait_closed()


class Recorder(asyncio.Protocol):
    """A plain protocol that records what happens to it."""

    def __init__(self, keep_open: bool = False) -> None:
        self.data = bytearray()
        self.got = asyncio.Event()
        self.eof = asyncio.Event()
        self.keep_open = keep_open
        self.lost: asyncio.Future[Exception | None] = asyncio.get_running_loop().create_future()

    def data_received(self, data: bytes) -> None:
        self.data += data
        self.got.set()

    def eof_received(self) -> bool:
        self.eof.set()
        return self.keep_open

    def connection_lost(self, exc: Exception | None) -> None:
        self.lost.set_result(exc)

    async def wait_for(self, size: int) -> None:
        while len(self.data) < size:
            self.got.clear()
            await asyncio.wait_for(self.got.wait(), STEP)


class BufferedRecorder(Recorder, asyncio.BufferedProtocol):
    """Reads into a buffer of its own, as asyncio feeds a BufferedProtocol."""

    def __init__(self) -> None:
        super().__init__()
        self.buffer = bytearray(64)
        self.get_buffer_calls = 0

    def get_buffer(self, sizehint: int) -> memoryview:
        self.get_buffer_calls += 1
        return memoryview(self.buffer)

    def buffer_updated(self, nbytes: int) -> None:
        self.data_received(bytes(self.buffer[:nbytes]))


class SelfReader(BufferedRecorder):
    """Reads the socket itself through the transport's hook."""

    def socket_reader(self, transport: SocketTransport) -> Callable[[], None]:
        self.transport = transport
        self.reads = 0
        return self.read

    def read(self) -> None:
        self.reads += 1
        try:
            nbytes = self.transport.recv_into(self.buffer)
        except BlockingIOError:
            return
        except OSError as exc:
            self.transport.read_failed(exc)
            return
        if nbytes:
            self.buffer_updated(nbytes)
        else:
            self.transport.read_eof()


async def closes_cleanly(transport: asyncio.BaseTransport, protocol: Recorder) -> None:
    """close() ends the connection with connection_lost(None)."""
    transport.close()
    assert await asyncio.wait_for(protocol.lost, STEP) is None


async def connect(port: int, factory: Callable[[], Any]) -> tuple[SocketTransport, Any]:
    loop = asyncio.get_running_loop()
    transport, protocol = await open_socket(loop, factory, "127.0.0.1", port)
    assert isinstance(transport, SocketTransport)
    return transport, protocol


@pytest.mark.parametrize("factory", [Recorder, BufferedRecorder, SelfReader])
async def test_reads_reach_every_kind_of_protocol(
    peer: tuple[Peer, int], factory: Callable[[], Recorder]
) -> None:
    side, port = peer
    transport, protocol = await connect(port, factory)
    _, writer = await side.ready()
    payload = bytes(range(256)) * 8  # more than a BufferedRecorder's buffer takes at once
    writer.write(payload)
    await protocol.wait_for(len(payload))
    assert protocol.data == payload
    if isinstance(protocol, SelfReader):
        assert protocol.reads >= len(payload) // 64
        assert protocol.get_buffer_calls == 0
    elif isinstance(protocol, BufferedRecorder):
        assert protocol.get_buffer_calls >= len(payload) // 64
    await closes_cleanly(transport, protocol)


@pytest.mark.parametrize("factory", [Recorder, SelfReader])
async def test_the_peer_closing_is_eof_then_connection_lost(
    peer: tuple[Peer, int], factory: Callable[[], Recorder]
) -> None:
    side, port = peer
    transport, protocol = await connect(port, factory)
    _, writer = await side.ready()
    writer.write(b"last words")
    writer.close()
    assert await asyncio.wait_for(protocol.lost, STEP) is None
    assert protocol.eof.is_set()
    assert protocol.data == b"last words"
    assert transport.is_closing()


async def test_eof_received_true_keeps_the_transport_open(peer: tuple[Peer, int]) -> None:
    side, port = peer
    transport, protocol = await connect(port, lambda: Recorder(keep_open=True))
    _, writer = await side.ready()
    writer.close()
    await asyncio.wait_for(protocol.eof.wait(), STEP)
    assert not transport.is_closing()
    assert not transport.is_reading()
    await closes_cleanly(transport, protocol)


async def test_a_reset_is_reported_with_its_error(peer: tuple[Peer, int]) -> None:
    side, port = peer
    _transport, protocol = await connect(port, SelfReader)
    _, writer = await side.ready()
    raw = writer.get_extra_info("socket")
    raw.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
    writer.transport.abort()  # closing with linger 0 sends a reset
    error = await asyncio.wait_for(protocol.lost, STEP)
    assert isinstance(error, ConnectionResetError)


async def test_what_the_socket_does_not_take_waits_and_goes_out_in_order(
    peer: tuple[Peer, int],
) -> None:
    side, port = peer
    transport, protocol = await connect(port, Recorder)
    reader, _ = await side.ready()
    payload = bytes(range(251)) * (BIG // 251)
    transport.write(payload[:1000])
    transport.write(memoryview(payload)[1000:])
    assert transport.get_write_buffer_size() > 0  # the peer reads nothing yet
    received = await asyncio.wait_for(reader.readexactly(len(payload)), 10 * STEP)
    assert received == payload
    assert transport.get_write_buffer_size() == 0
    await closes_cleanly(transport, protocol)


async def test_close_sends_what_is_pending_first(peer: tuple[Peer, int]) -> None:
    side, port = peer
    transport, protocol = await connect(port, Recorder)
    reader, _ = await side.ready()
    payload = b"x" * BIG
    transport.write(payload)
    transport.close()
    assert transport.is_closing()
    assert not protocol.lost.done()
    transport.write(b"after close")  # ignored
    received = await asyncio.wait_for(reader.read(), 10 * STEP)  # to EOF
    assert received == payload
    assert await asyncio.wait_for(protocol.lost, STEP) is None


async def test_abort_drops_what_is_pending(peer: tuple[Peer, int]) -> None:
    side, port = peer
    transport, protocol = await connect(port, Recorder)
    reader, _ = await side.ready()
    transport.write(b"y" * BIG)
    pending = transport.get_write_buffer_size()
    assert pending > 0
    transport.abort()
    assert transport.get_write_buffer_size() == 0
    assert await asyncio.wait_for(protocol.lost, STEP) is None
    received = await asyncio.wait_for(reader.read(), 10 * STEP)
    assert len(received) == BIG - pending


async def test_extra_info_writes_of_the_wrong_type_and_repr(peer: tuple[Peer, int]) -> None:
    side, port = peer
    transport, protocol = await connect(port, Recorder)
    await side.ready()
    sock = transport.get_extra_info("socket")
    assert isinstance(sock, socket.socket)
    assert transport.get_extra_info("peername") == ("127.0.0.1", port)
    assert transport.get_extra_info("sockname") == sock.getsockname()
    assert transport.get_extra_info("nothing", 7) == 7
    assert sock.getsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY)
    assert not transport.can_write_eof()
    with pytest.raises(TypeError, match="bytes-like"):
        transport.write("text")  # type: ignore[arg-type]
    assert "open" in repr(transport)
    transport.close()
    await asyncio.wait_for(protocol.lost, STEP)
    assert "closed" in repr(transport)


async def test_pause_resume_and_a_new_protocol(peer: tuple[Peer, int]) -> None:
    side, port = peer
    transport, first = await connect(port, Recorder)
    _, writer = await side.ready()
    transport.pause_reading()
    assert not transport.is_reading()
    second = SelfReader()
    transport.set_protocol(second)
    assert transport.get_protocol() is second
    assert not transport.is_reading()  # still paused
    writer.write(b"for the second")
    transport.resume_reading()
    await second.wait_for(len(b"for the second"))
    assert second.data == b"for the second"
    assert first.data == b""
    await closes_cleanly(transport, second)


async def test_a_loop_without_reader_callbacks_gets_asyncios_transport(
    peer: tuple[Peer, int], monkeypatch: pytest.MonkeyPatch
) -> None:
    side, port = peer
    loop = asyncio.get_running_loop()

    def unsupported(*args: Any) -> None:
        raise NotImplementedError

    monkeypatch.setattr(loop, "add_reader", unsupported)
    transport, made = await open_socket(loop, Recorder, "127.0.0.1", port)
    monkeypatch.undo()
    assert isinstance(made, Recorder)
    protocol = made
    assert not isinstance(transport, SocketTransport)
    _, writer = await side.ready()
    writer.write(b"still works")
    await protocol.wait_for(len(b"still works"))
    await closes_cleanly(transport, protocol)


def closed_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port: int = probe.getsockname()[1]
    return port  # nothing listens there now


async def test_connect_tries_each_address_in_turn(
    peer: tuple[Peer, int], monkeypatch: pytest.MonkeyPatch
) -> None:
    side, port = peer
    loop = asyncio.get_running_loop()
    refused = ("127.0.0.1", closed_port())
    addresses = [refused, ("127.0.0.1", port)]

    async def getaddrinfo(*args: Any, **kwargs: Any) -> list[tuple[Any, ...]]:
        return [(socket.AF_INET, socket.SOCK_STREAM, 6, "", address) for address in addresses]

    monkeypatch.setattr(loop, "getaddrinfo", getaddrinfo)
    transport, made = await open_socket(loop, Recorder, "anything", 0)
    assert isinstance(made, Recorder)
    protocol = made
    await side.ready()
    transport.close()
    await asyncio.wait_for(protocol.lost, STEP)
    addresses = [refused, refused]
    with pytest.raises(OSError, match="every address failed"):
        await open_socket(loop, Recorder, "anything", 0)
    addresses = []
    with pytest.raises(OSError, match="no address"):
        await open_socket(loop, Recorder, "anything", 0)


async def test_a_refused_connection_is_a_connection_error() -> None:
    loop = asyncio.get_running_loop()
    port = closed_port()
    with pytest.raises(ConnectionRefusedError):
        await open_socket(loop, Recorder, "127.0.0.1", port)
    with pytest.raises(GalileoConnectionError, match="cannot connect"):
        await socket_connector("127.0.0.1", port)(loop, Recorder)
