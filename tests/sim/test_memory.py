"""The in-memory transport pair behaves like a socket pair for asyncio protocols."""

from __future__ import annotations

import asyncio

import pytest

from galileo_async.sim.memory import MemoryTransport, create_transport_pair


class Recorder(asyncio.Protocol):
    """Records every callback in order."""

    def __init__(self) -> None:
        self.events: list[tuple[str, object]] = []
        self.transport: asyncio.BaseTransport | None = None
        self.lost = asyncio.get_running_loop().create_future()

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        self.transport = transport
        self.events.append(("made", None))

    def data_received(self, data: bytes) -> None:
        self.events.append(("data", data))

    def connection_lost(self, exc: Exception | None) -> None:
        self.events.append(("lost", exc))
        self.lost.set_result(exc)

    @property
    def data(self) -> bytes:
        return b"".join(value for kind, value in self.events if kind == "data")  # type: ignore[misc]


async def test_connection_made_on_both_before_return() -> None:
    a, b = Recorder(), Recorder()
    ta, tb = create_transport_pair(a, b)
    assert a.events == [("made", None)]
    assert b.events == [("made", None)]
    assert a.transport is ta
    assert b.transport is tb
    assert ta.get_protocol() is a
    assert tb.get_protocol() is b
    ta.close()
    await asyncio.wait_for(b.lost, 1)


async def test_write_arrives_later_in_order_as_separate_chunks() -> None:
    a, b = Recorder(), Recorder()
    ta, tb = create_transport_pair(a, b)
    ta.write(b"one")
    ta.write(bytearray(b"two"))
    tb.write(memoryview(b"back"))
    assert b.events == [("made", None)]  # delivery goes through the loop, never re-entrantly
    await asyncio.sleep(0)
    assert b.events[1:] == [("data", b"one"), ("data", b"two")]
    assert a.data == b"back"
    assert ta.bytes_written == 6
    ta.close()
    await asyncio.wait_for(a.lost, 1)


async def test_close_delivers_pending_data_then_loses_both() -> None:
    a, b = Recorder(), Recorder()
    ta, tb = create_transport_pair(a, b)
    ta.write(b"last words")
    ta.close()
    assert ta.is_closing()
    assert tb.is_closing()
    assert await asyncio.wait_for(a.lost, 1) is None
    assert await asyncio.wait_for(b.lost, 1) is None
    assert b.events[1:] == [("data", b"last words"), ("lost", None)]
    ta.write(b"ignored")
    tb.write(b"ignored")
    ta.close()  # idempotent
    await asyncio.sleep(0)
    assert [kind for kind, _ in a.events].count("lost") == 1
    assert b.data == b"last words"


async def test_closing_end_gets_no_more_data() -> None:
    a, b = Recorder(), Recorder()
    ta, tb = create_transport_pair(a, b)
    tb.write(b"in flight")
    ta.close()
    await asyncio.wait_for(a.lost, 1)
    assert a.data == b""


async def test_abort_reports_reset_to_peer() -> None:
    a, b = Recorder(), Recorder()
    ta, _ = create_transport_pair(a, b)
    ta.abort()
    assert await asyncio.wait_for(a.lost, 1) is None
    assert isinstance(await asyncio.wait_for(b.lost, 1), ConnectionResetError)


async def test_extra_info_and_flow_control_no_ops() -> None:
    a, b = Recorder(), Recorder()
    ta, tb = create_transport_pair(a, b, extra_a={"name": "host"})
    assert ta.get_extra_info("name") == "host"
    assert ta.get_extra_info("peername") == "memory"
    assert tb.get_extra_info("missing", 7) == 7
    assert ta.is_reading()
    ta.pause_reading()
    assert not ta.is_reading()
    tb.write(b"still delivered")
    await asyncio.sleep(0)
    assert a.data == b"still delivered"
    ta.resume_reading()
    assert ta.is_reading()
    ta.set_write_buffer_limits(high=10)
    assert ta.get_write_buffer_size() == 0
    assert not ta.can_write_eof()
    with pytest.raises(NotImplementedError):
        ta.write_eof()
    ta.writelines([b"a", b"b"])
    await asyncio.sleep(0)
    assert b.data == b"ab"
    assert isinstance(ta, asyncio.Transport)
    assert isinstance(ta, MemoryTransport)
    ta.close()
    await asyncio.wait_for(b.lost, 1)


async def test_works_with_streams() -> None:
    """Any asyncio Protocol works, including the standard streams."""
    loop = asyncio.get_running_loop()
    reader = asyncio.StreamReader()
    client = asyncio.StreamReaderProtocol(reader)
    echo = Recorder()
    client_transport, echo_transport = create_transport_pair(client, echo, loop=loop)
    writer = asyncio.StreamWriter(client_transport, client, reader, loop)
    echo_transport.write(b"hello\n")
    assert await asyncio.wait_for(reader.readline(), 1) == b"hello\n"
    writer.write(b"ping")
    await writer.drain()
    await asyncio.sleep(0)
    assert echo.data == b"ping"
    writer.close()
    await asyncio.wait_for(writer.wait_closed(), 1)
    await asyncio.wait_for(echo.lost, 1)
