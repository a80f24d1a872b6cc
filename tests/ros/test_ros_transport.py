"""TCPROS framing and connections, XML-RPC client and slave server, ros:// URLs (loopback)."""

from __future__ import annotations

import asyncio
import socket
import struct
from collections.abc import AsyncIterator

import pytest
from hypothesis import given
from hypothesis import strategies as st

from galileo_async.errors import GalileoConnectionError, InvalidArgument
from galileo_async.links import open_link
from galileo_async.ros import RosChannel, parse_ros_url
from galileo_async.ros.tcpros import (
    MAX_FRAME,
    Framer,
    TcprosError,
    TcprosPublisher,
    decode_header,
    encode_header,
    frame,
    subscribe,
)
from galileo_async.ros.xmlrpc import (
    MasterClient,
    RosApiError,
    SlaveServer,
    request_topic,
    xmlrpc_call,
)
from galileo_async.state import StatusStore
from galileo_async.transports.connectors import KEEPALIVE_COUNT, KEEPALIVE_IDLE, KEEPALIVE_INTERVAL
from tests.support.ports import refused_port

pytestmark = pytest.mark.timeout(30)
TOPIC = "/galileo/cmds"


def test_header_round_trip() -> None:
    fields = {"callerid": "/me", "topic": TOPIC, "message_definition": "a=b\nc d", "md5sum": "*"}
    data = encode_header(fields)
    (size,) = struct.unpack_from("<I", data)
    assert size == len(data) - 4
    assert decode_header(data[4:]) == fields


def test_bad_headers_raise() -> None:
    with pytest.raises(TcprosError):
        decode_header(b"\x05\x00\x00\x00abc")
    with pytest.raises(TcprosError):
        decode_header(frame(b"no-equals-sign"))
    with pytest.raises(TcprosError):
        decode_header(b"\x01\x00")


@given(
    st.lists(st.binary(max_size=300), max_size=8),
    st.lists(st.integers(min_value=1, max_value=50), min_size=1),
)
def test_framer_any_chunking(messages: list[bytes], cuts: list[int]) -> None:
    stream = b"".join(frame(msg) for msg in messages)
    framer = Framer()
    out: list[bytes] = []
    offset = 0
    i = 0
    while offset < len(stream):
        step = cuts[i % len(cuts)]
        out += framer.feed(stream[offset : offset + step])
        offset += step
        i += 1
    assert out == messages


def test_framer_refuses_oversized_frames() -> None:
    with pytest.raises(TcprosError):
        Framer().feed(struct.pack("<I", MAX_FRAME + 1))


@pytest.fixture
async def publisher() -> AsyncIterator[TcprosPublisher]:
    pub = TcprosPublisher(
        topic=TOPIC, msg_type="pkg/Msg", md5sum="0123", definition="int32 x\n", caller_id="/pub"
    )
    await pub.start("127.0.0.1")
    try:
        yield pub
    finally:
        await pub.close()


async def test_publisher_delivers_to_subscribers(publisher: TcprosPublisher) -> None:
    assert publisher.port is not None
    received: asyncio.Queue[bytes] = asyncio.Queue()
    closed: asyncio.Future[Exception | None] = asyncio.get_running_loop().create_future()
    header = {"callerid": "/sub", "topic": TOPIC, "md5sum": "*", "type": "*", "tcp_nodelay": "1"}
    transport, reply = await subscribe(
        "127.0.0.1", publisher.port, header, received.put_nowait,
        lambda exc: closed.set_result(exc), timeout=2,
    )  # fmt: skip
    try:
        assert reply["md5sum"] == "0123"
        assert reply["message_definition"] == "int32 x\n"
        assert reply["type"] == "pkg/Msg"
        assert await publisher.wait_for_subscriber(2)
        assert publisher.publish(b"one") == 1
        assert publisher.publish(b"") == 1
        assert await asyncio.wait_for(received.get(), 2) == b"one"
        assert await asyncio.wait_for(received.get(), 2) == b""
        await publisher.close()  # the subscriber sees the publisher go away
        await asyncio.wait_for(closed, 2)
    finally:
        transport.abort()


def assert_keepalive(sock: socket.socket) -> None:
    assert sock.getsockopt(socket.SOL_SOCKET, socket.SO_KEEPALIVE) != 0
    if hasattr(socket, "TCP_KEEPIDLE"):
        assert sock.getsockopt(socket.IPPROTO_TCP, socket.TCP_KEEPIDLE) == KEEPALIVE_IDLE
    if hasattr(socket, "TCP_KEEPINTVL"):
        assert sock.getsockopt(socket.IPPROTO_TCP, socket.TCP_KEEPINTVL) == KEEPALIVE_INTERVAL
    if hasattr(socket, "TCP_KEEPCNT"):
        assert sock.getsockopt(socket.IPPROTO_TCP, socket.TCP_KEEPCNT) == KEEPALIVE_COUNT


async def test_both_ends_of_a_topic_connection_use_tcp_keepalive(
    publisher: TcprosPublisher,
) -> None:
    """A peer whose host vanished sends no FIN: only keepalive probes can report it."""
    assert publisher.port is not None
    header = {"callerid": "/sub", "topic": TOPIC, "md5sum": "*", "type": "*"}
    transport, _ = await subscribe("127.0.0.1", publisher.port, header, print, print, timeout=2)
    try:
        assert await publisher.wait_for_subscriber(2)
        assert_keepalive(transport.get_extra_info("socket"))
        (connection,) = publisher._connections
        assert connection.transport is not None
        assert_keepalive(connection.transport.get_extra_info("socket"))
    finally:
        transport.abort()


async def test_publisher_refuses_a_wrong_md5(publisher: TcprosPublisher) -> None:
    assert publisher.port is not None
    header = {"callerid": "/sub", "topic": TOPIC, "md5sum": "ffff", "type": "pkg/Msg"}
    with pytest.raises(TcprosError, match="md5sum mismatch"):
        await subscribe("127.0.0.1", publisher.port, header, print, print, timeout=2)
    assert publisher.subscriber_count == 0
    assert publisher.publish(b"x") == 0
    assert not await publisher.wait_for_subscriber(0.05)


async def test_subscribe_to_nothing_is_a_connection_error() -> None:
    with refused_port() as port, pytest.raises(GalileoConnectionError):
        await subscribe("127.0.0.1", port, {}, print, print, timeout=1)


@pytest.fixture
async def slave() -> AsyncIterator[SlaveServer]:
    server = SlaveServer("/node", "http://127.0.0.1:1/")
    await server.start("127.0.0.1")
    try:
        yield server
    finally:
        await server.close()


async def test_slave_server_answers_request_topic(slave: SlaveServer) -> None:
    assert slave.uri is not None
    slave.publications[TOPIC] = ("pkg/Msg", ("127.0.0.1", 4242))
    assert await request_topic(slave.uri, "/peer", TOPIC, timeout=2) == ("127.0.0.1", 4242)
    with pytest.raises(RosApiError, match="not a publisher"):
        await request_topic(slave.uri, "/peer", "/other", timeout=2)
    assert (await xmlrpc_call(slave.uri, "getPid", "/peer", timeout=2))[0] == 1
    pubs = await xmlrpc_call(slave.uri, "getPublications", "/peer", timeout=2)
    assert pubs == [1, "", [[TOPIC, "pkg/Msg"]]]
    unknown = await xmlrpc_call(slave.uri, "noSuchMethod", "/peer", timeout=2)
    assert unknown[0] == -1


async def test_slave_server_forwards_publisher_updates(slave: SlaveServer) -> None:
    assert slave.uri is not None
    seen: list[list[str]] = []
    slave.subscriptions["/galileo/status"] = ("pkg/Status", seen.append)
    result = await xmlrpc_call(
        slave.uri, "publisherUpdate", "/master", "/galileo/status", ["http://a:1/"], timeout=2
    )
    assert result == [1, "", 0]
    assert seen == [["http://a:1/"]]


async def test_master_client_errors_are_connection_errors() -> None:
    with refused_port() as port:
        client = MasterClient(f"http://127.0.0.1:{port}/", "/me", timeout=0.5)
        with pytest.raises(RosApiError):
            await client.get_pid()
    with pytest.raises(RosApiError):
        MasterClient("ftp://nowhere/", "/me")


async def test_master_client_reports_failure_codes(slave: SlaveServer) -> None:
    assert slave.uri is not None
    # A slave API is no master: registerPublisher is unknown there, code -1.
    client = MasterClient(slave.uri, "/me", timeout=1)
    with pytest.raises(RosApiError, match="code -1"):
        await client.register_publisher(TOPIC, "pkg/Msg", "http://127.0.0.1:1/")


def test_parse_ros_url() -> None:
    assert parse_ros_url("ros://robot.local") == ("http://robot.local:11311/", {})
    uri, options = parse_ros_url("ros://10.0.0.5:11312?host=10.0.0.9&node_name=/ops")
    assert uri == "http://10.0.0.5:11312/"
    assert options == {"host": "10.0.0.9", "node_name": "/ops"}
    assert parse_ros_url("ros://[::1]:5")[0] == "http://[::1]:5/"
    for bad in (
        "ros://",
        "http://x",
        "ros://x?what=1",
        "ros://x:99999",
        "ros://x?connect_timeout=z",
    ):
        with pytest.raises(InvalidArgument):
            parse_ros_url(bad)


async def test_open_link_ros_options() -> None:
    store = StatusStore()
    link = open_link("ros://127.0.0.1:1?node_name=/n", store, baudrate=9600, reconnect=False)
    assert isinstance(link.channel, RosChannel)
    assert link.channel.node_name == "/n"
    assert not link.reconnect
    with pytest.raises(InvalidArgument):
        open_link("ros://127.0.0.1:1", StatusStore(), layout="v1")
    await link.close()


async def test_slave_server_on_ipv6_loopback() -> None:
    server = SlaveServer("/node6", "http://[::1]:1/")
    uri = await server.start("::1")
    try:
        assert uri.startswith("http://[::1]:")
        assert await xmlrpc_call(uri, "getMasterUri", "/peer", timeout=2) == [
            1,
            "",
            "http://[::1]:1/",
        ]
    finally:
        await server.close()


async def test_a_message_in_the_same_read_as_the_reply_comes_after_on_handshake() -> None:
    """on_handshake runs before any message is delivered, even one read with the header."""
    reply = encode_header({"callerid": "/pub", "type": "pkg/Msg", "md5sum": "*"})

    class Latched(asyncio.Protocol):
        def connection_made(self, transport: asyncio.BaseTransport) -> None:
            self.transport = transport

        def data_received(self, data: bytes) -> None:
            assert isinstance(self.transport, asyncio.Transport)
            self.transport.write(reply + frame(b"latched"))

    server = await asyncio.get_running_loop().create_server(Latched, "127.0.0.1", 0)
    port = server.sockets[0].getsockname()[1]
    seen: list[str] = []
    header = {"callerid": "/sub", "topic": TOPIC, "md5sum": "*", "type": "*"}
    try:
        transport, got = await subscribe(
            "127.0.0.1", port, header, lambda m: seen.append(m.decode()), print,
            timeout=2, on_handshake=lambda h: seen.append(f"header {h['type']}"),
        )  # fmt: skip
        transport.abort()
        assert got["type"] == "pkg/Msg"
        assert seen == ["header pkg/Msg", "latched"]

        def refuse(h: dict[str, str]) -> None:
            raise ValueError(f"not this type: {h['type']}")

        seen.clear()
        with pytest.raises(ValueError, match="not this type: pkg/Msg"):
            await subscribe(
                "127.0.0.1", port, header, lambda m: seen.append("message"), print,
                timeout=2, on_handshake=refuse,
            )  # fmt: skip
        assert seen == []
    finally:
        server.close()
        await server.wait_closed()
