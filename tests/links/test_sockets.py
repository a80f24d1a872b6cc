"""socket:// links on asyncio's own TCP transport, over 127.0.0.1."""

from __future__ import annotations

import asyncio
import socket
import struct
from collections.abc import AsyncIterator

import pytest

from galileo_async import events as ev
from galileo_async.errors import GalileoConnectionError
from galileo_async.links import open_link
from galileo_async.protocol import CommandDecoder, Goto
from galileo_async.state import StatusStore
from galileo_async.transports import Link, StreamChannel
from galileo_async.transports.connectors import socket_connector
from tests.support.fake_device import status_frame

STEP = 2.0  # upper bound for anything that should happen promptly
BIG = 4 << 20  # more than a loopback socket takes without its peer reading
SMALL_BUFFER = 64 << 10  # SO_RCVBUF / SO_SNDBUF of the sockets that must fill up


class Peer:
    """The device side of one socket:// connection, on asyncio streams."""

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
async def peer() -> AsyncIterator[tuple[Peer, str]]:
    side = Peer()
    listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    # Small kernel buffers (inherited by the accepted socket): a peer that does not read
    # then fills up after a bounded number of bytes, however the machine tunes loopback.
    listener.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, SMALL_BUFFER)
    listener.bind(("127.0.0.1", 0))
    server = await asyncio.start_server(side.accept, sock=listener)
    port = server.sockets[0].getsockname()[1]
    yield side, f"socket://127.0.0.1:{port}"
    if side.writer is not None:
        side.writer.close()
    server.close()
    await server.wait_closed()


async def socket_link(links: list[Link], url: str, **options: object) -> tuple[Link, StatusStore]:
    store = StatusStore()
    link = open_link(url, store, reconnect=False, stale_timeout=None, **options)
    assert isinstance(link.channel, StreamChannel)
    links.append(link)
    await link.open()
    return link, store


async def test_a_socket_link_runs_on_asyncios_transport_with_nodelay(
    peer: tuple[Peer, str], links: list[Link]
) -> None:
    side, url = peer
    link, store = await socket_link(links, url)
    _, writer = await side.ready()
    transport = link.channel.transport
    assert isinstance(transport, asyncio.Transport)
    sock = transport.get_extra_info("socket")
    assert sock.getsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY)
    writer.write(b"".join(status_frame(stamp) for stamp in range(1, 101)))
    await store.wait_until(lambda s: s.time_stamp == 100, timeout=STEP)


async def test_the_peer_closing_is_a_lost_connection(
    peer: tuple[Peer, str], links: list[Link]
) -> None:
    side, url = peer
    link, store = await socket_link(links, url)
    events = store.events()
    _, writer = await side.ready()
    writer.write(status_frame(1))
    writer.close()
    lost = await asyncio.wait_for(anext(events), STEP)
    assert isinstance(lost, ev.ConnectionLostEvent)
    assert "closed by the peer" in lost.reason
    assert store.status is not None
    assert store.status.time_stamp == 1  # the last words arrived first
    assert not link.connected


async def test_a_reset_is_a_lost_connection_with_its_error(
    peer: tuple[Peer, str], links: list[Link]
) -> None:
    side, url = peer
    link, store = await socket_link(links, url)
    events = store.events()
    _, writer = await side.ready()
    raw = writer.get_extra_info("socket")
    raw.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
    writer.transport.abort()  # closing with linger 0 sends a reset
    lost = await asyncio.wait_for(anext(events), STEP)
    assert isinstance(lost, ev.ConnectionLostEvent)
    assert "reset" in lost.reason.lower()
    assert not link.connected


async def test_a_peer_that_does_not_read_holds_sends_back_and_the_buffer_stays_bounded(
    peer: tuple[Peer, str], links: list[Link]
) -> None:
    side, url = peer
    link, _ = await socket_link(links, url, drain_timeout=0.05, min_command_interval=0)
    reader, writer = await side.ready()
    writer.transport.pause_reading()  # the peer reads nothing until told to
    transport = link.channel.transport
    assert transport is not None
    transport.get_extra_info("socket").setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, SMALL_BUFFER)
    transport.write(b"\0" * BIG)  # the peer reads nothing yet: the socket stops taking bytes
    held = transport.get_write_buffer_size()
    assert held > 0
    results = await asyncio.wait_for(
        asyncio.gather(*(link.send(Goto(i)) for i in range(20)), return_exceptions=True), STEP
    )
    for result in results:
        assert isinstance(result, GalileoConnectionError)
        assert "unsent bytes" in str(result)
    # Nothing was written into the full buffer (the kernel may still have taken some of it);
    # the bytes read below prove it: BIG zero bytes, then only Goto(7).
    assert transport.get_write_buffer_size() <= held
    assert link.connected  # the link stays up: the stale timer judges the peer
    writer.transport.resume_reading()
    assert (await asyncio.wait_for(reader.readexactly(BIG), 10 * STEP)) == b"\0" * BIG
    await asyncio.wait_for(link.send(Goto(7)), STEP)
    data = await asyncio.wait_for(reader.read(64), STEP)
    assert CommandDecoder().feed(data) == [Goto(7)]


async def test_a_refused_connection_is_a_connection_error(links: list[Link]) -> None:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]  # nothing listens there once the probe closes
    loop = asyncio.get_running_loop()
    with pytest.raises(GalileoConnectionError, match="cannot connect"):
        await socket_connector("127.0.0.1", port)(loop, asyncio.Protocol)
    link = open_link(f"socket://127.0.0.1:{port}", StatusStore(), reconnect=False)
    links.append(link)
    with pytest.raises(GalileoConnectionError, match="cannot connect"):
        await link.open()
