"""Link over a StreamChannel over a TCP loopback fake robot and an in-memory transport."""

from __future__ import annotations

import asyncio
import concurrent.futures
import itertools
import logging
import socket
import sys
import time
import types
from collections.abc import Callable
from typing import Any

import pytest

from galileo_async import events as ev
from galileo_async.errors import (
    ConnectionLost,
    GalileoConnectionError,
    InvalidArgument,
    LinkStale,
)
from galileo_async.links import open_link
from galileo_async.models import GalileoStatus, StatusLayout
from galileo_async.protocol import CommandDecoder, DecoderStats, Goto, Pause, Stop, encode
from galileo_async.state import StatusStore
from galileo_async.transports import Link, LinkState, LinkStats, StreamChannel
from galileo_async.transports.connectors import KEEPALIVE_COUNT, KEEPALIVE_IDLE, KEEPALIVE_INTERVAL
from galileo_async.transports.stream import READ_SIZE, _read_buffer
from tests.support.fake_device import FakeDevice, MemoryConnector, RecordingTransport, status_frame

STEP = 2.0  # upper bound for anything that should happen promptly
FAST = {"reconnect_initial": 0.01, "reconnect_max": 0.05, "stale_timeout": 5.0}


async def connect(
    device: FakeDevice, links: list[Link], **options: Any
) -> tuple[Link, StatusStore]:
    store = StatusStore()
    link = open_link(device.url, store, **{**FAST, **options})
    links.append(link)
    await link.open()
    await device.wait_for(lambda: len(device.clients) == 1)
    return link, store


async def in_memory(links: list[Link], **options: Any) -> tuple[MemoryConnector, Link]:
    connector = MemoryConnector()
    link = Link(StreamChannel(connector), StatusStore(), **options)
    links.append(link)
    await link.open()
    return connector, link


async def test_status_flows_and_is_counted(device: FakeDevice, links: list[Link]) -> None:
    link, store = await connect(device, links)
    assert isinstance(link.channel, StreamChannel)
    assert link.connected
    assert link.stats.connected
    assert link.stats.last_frame_age is None
    device.push_raw(b"\x00garbage" + status_frame(1))
    device.time_stamp = 1
    device.push(nav_status=1)
    device.time_stamp = 5  # frames 3 and 4 never sent
    device.push()
    status = await store.wait_until(lambda s: s.time_stamp == 6, timeout=STEP)
    assert status.layout is StatusLayout.V2
    stats = link.stats
    assert stats.frames == 3
    assert stats.bytes_received == 8 + 3 * 89
    assert stats.bytes_discarded == 8
    assert stats.resyncs == 1
    assert stats.lost_frames == 3
    assert stats.layout is StatusLayout.V2
    age = stats.last_frame_age
    assert age is not None
    assert 0 <= age < STEP


def test_link_stats_hold_the_decoders_counters_not_inherit_them() -> None:
    link = open_link("socket://127.0.0.1:9", StatusStore())
    assert isinstance(link.channel, StreamChannel)
    assert not issubclass(LinkStats, DecoderStats)
    assert link.channel.decoder.stats is link.stats.decoder  # the decoder counts straight into it
    link.stats.decoder.frames = 2
    assert link.stats.frames == 2


async def test_pacing_one_command_per_write_fifo_on_the_wire(
    device: FakeDevice, links: list[Link]
) -> None:
    link, _ = await connect(device, links)
    commands = [Goto(i) for i in range(12)]
    await asyncio.wait_for(asyncio.gather(*(link.send(c) for c in commands)), STEP)
    await device.wait_for(lambda: len(device.commands) == 12)
    assert device.commands == commands  # FIFO
    assert link.stats.commands_sent == 12
    for _, chunk in device.writes:
        assert len(CommandDecoder().feed(chunk)) == 1  # never two commands in one write
    # The gaps are asserted where they are made, on the transport (the next test): arrival
    # times over loopback carry the receiver's scheduling, which a loaded machine delays.


async def test_pacing_measured_at_the_transport(links: list[Link]) -> None:
    connector, link = await in_memory(links, min_command_interval=0.010)
    commands = [Goto(1), Pause(), Stop(50), Goto(2), Goto(3)]
    await asyncio.wait_for(asyncio.gather(*(link.send(c) for c in commands)), STEP)
    writes = connector.transport.writes
    assert [data for _, data in writes] == [encode(c) for c in commands]
    times = [t for t, _ in writes]
    assert all(b - a >= 0.010 for a, b in itertools.pairwise(times))
    # The interval is between consecutive writes, not between calls: a later send waits too.
    await link.send(Goto(4))
    assert connector.transport.writes[-1][0] - times[-1] >= 0.010


async def test_send_returns_once_written_and_cancelled_sends_are_skipped(
    links: list[Link],
) -> None:
    connector, link = await in_memory(links, min_command_interval=0.02)
    await link.send(Goto(1))
    assert connector.transport.writes[-1][1] == encode(Goto(1))
    second = asyncio.create_task(link.send(Goto(2)))
    third = asyncio.create_task(link.send(Goto(3)))
    await asyncio.sleep(0)
    second.cancel()
    await asyncio.wait_for(third, STEP)
    assert [d for _, d in connector.transport.writes] == [encode(Goto(1)), encode(Goto(3))]
    assert second.cancelled()


async def test_a_failing_write_fails_its_send_only(
    caplog: pytest.LogCaptureFixture, links: list[Link]
) -> None:
    connector, link = await in_memory(links)
    connector.transport.write_error = RuntimeError("driver bug")
    with pytest.raises(GalileoConnectionError, match="driver bug"):
        await asyncio.wait_for(link.send(Goto(1)), STEP)
    await asyncio.wait_for(link.send(Goto(2)), STEP)  # the writer survived
    assert [d for _, d in connector.transport.writes] == [encode(Goto(2))]
    assert link.stats.commands_sent == 1


async def test_peer_close_fails_every_waiter_at_once(device: FakeDevice, links: list[Link]) -> None:
    link, store = await connect(device, links, reconnect=False)
    events = store.events()
    device.push()
    await store.wait_until(lambda s: s.time_stamp == 1, timeout=STEP)
    waiter = asyncio.create_task(store.wait_until(lambda s: s.navigating, timeout=60))
    watch = store.watch()
    reader = asyncio.create_task(watch.next(timeout=60))
    await asyncio.sleep(0)
    with watch:
        await device.drop_clients()  # a clean close from the robot side counts as a drop
        for task in (waiter, reader):
            with pytest.raises(ConnectionLost):
                await asyncio.wait_for(task, STEP)
    assert not link.connected
    event = await asyncio.wait_for(anext(events), STEP)
    assert isinstance(event, ev.ConnectionLostEvent)
    with pytest.raises(ConnectionLost):
        await link.send(Goto(1))
    # Without reconnect nothing will feed the store again: its iterators end.
    with pytest.raises(StopAsyncIteration):
        await asyncio.wait_for(anext(store.statuses()), STEP)


async def test_eof_counts_as_a_drop(device: FakeDevice, links: list[Link]) -> None:
    _link, store = await connect(device, links, reconnect=False)
    waiter = asyncio.create_task(store.wait_until(lambda s: False, timeout=60))
    await asyncio.sleep(0)
    transport = device.clients[0].transport
    assert transport is not None
    transport.write_eof()
    with pytest.raises(ConnectionLost):
        await asyncio.wait_for(waiter, STEP)


async def test_pending_sends_fail_on_loss(links: list[Link]) -> None:
    connector, link = await in_memory(links, reconnect=False, min_command_interval=0.05)
    await link.send(Goto(1))
    pending = [asyncio.create_task(link.send(Goto(i))) for i in (2, 3)]
    await asyncio.sleep(0)
    connector.transport.lose(OSError("unplugged"))
    for task in pending:
        with pytest.raises(ConnectionLost, match="unplugged"):
            await asyncio.wait_for(task, STEP)
    assert len(connector.transport.writes) == 1


async def test_reads_from_a_replaced_connection_are_ignored(links: list[Link]) -> None:
    connector, link = await in_memory(links, reconnect_initial=0.01)
    store = link.store
    assert isinstance(store, StatusStore)
    events = store.events()
    connector.feed(status_frame(1))
    old = connector.transport
    old.lose(OSError("unplugged"))
    assert isinstance(await asyncio.wait_for(anext(events), STEP), ev.ConnectionLostEvent)
    await connector.wait_connects(2)
    frames = link.stats.frames
    old.protocol.data_received(status_frame(99))  # a late read from the old transport
    assert (link.stats.frames, store.status and store.status.time_stamp) == (frames, 1)
    assert link.state is LinkState.LOST  # a late read does not restore the link either
    connector.feed(status_frame(2))
    assert isinstance(await asyncio.wait_for(anext(events), STEP), ev.ConnectionRestored)
    assert store.status is not None
    assert store.status.time_stamp == 2


async def test_reconnects_after_the_server_restarts(device: FakeDevice, links: list[Link]) -> None:
    link, store = await connect(device, links)
    events = store.events()
    device.push()
    device.push()
    await store.wait_until(lambda s: s.time_stamp == 2, timeout=STEP)
    await device.stop()
    lost = await asyncio.wait_for(anext(events), STEP)
    assert isinstance(lost, ev.ConnectionLostEvent)
    assert not link.connected
    with pytest.raises(ConnectionLost, match="reconnecting"):
        await link.send(Goto(1))
    await device.start()  # same port
    await device.wait_for(lambda: len(device.clients) == 1)
    device.time_stamp = 0  # the serial node restarted: its counter starts again
    device.push()
    restored = await asyncio.wait_for(anext(events), STEP)
    assert isinstance(restored, ev.ConnectionRestored)  # once a frame came
    assert link.connected
    assert link.stats.reconnects == 1
    await store.wait_until(lambda s: s.time_stamp == 1, timeout=STEP)
    assert link.stats.lost_frames == 0
    await link.send(Goto(7))
    await device.wait_for(lambda: Goto(7) in device.commands)


async def test_reconnect_backs_off_exponentially_up_to_the_cap(links: list[Link]) -> None:
    connector, link = await in_memory(links, reconnect_initial=0.01, reconnect_max=0.04)
    store = link.store
    events = store.events()
    connector.failures = 5
    connector.transport.lose(None)
    assert isinstance(await asyncio.wait_for(anext(events), STEP), ev.ConnectionLostEvent)
    await connector.wait_connects(2)
    assert link.connected
    assert link.stats.reconnects == 1
    attempts = connector.attempts[1:]  # the first entry is open()
    assert len(attempts) == 6
    gaps = [b - a for a, b in itertools.pairwise(attempts)]
    for gap, expected in zip(gaps, [0.02, 0.04, 0.04, 0.04, 0.04], strict=True):
        assert gap >= expected * 0.99
    assert max(gaps[2:]) < 0.04 + 0.5  # capped: doubling would reach 0.32 s


async def test_reconnect_can_be_switched_off(links: list[Link]) -> None:
    connector, link = await in_memory(links, reconnect=False)
    events = link.store.events()
    connector.transport.lose(None)
    assert isinstance(await asyncio.wait_for(anext(events), STEP), ev.ConnectionLostEvent)
    with pytest.raises(StopAsyncIteration):  # the store closes: nothing will feed it again
        await asyncio.wait_for(anext(events), STEP)
    assert len(connector.attempts) == 1
    assert not link.connected
    assert not [t for t in asyncio.all_tasks() if "reconnect" in t.get_name()]
    await link.close()


async def test_stale_watchdog_fails_waiters_and_recovers(
    device: FakeDevice, links: list[Link]
) -> None:
    link, store = await connect(device, links, stale_timeout=0.1)
    events = store.events()
    device.start_stream(0.01)
    await store.wait_until(lambda s: (s.time_stamp or 0) >= 3, timeout=STEP)
    waiter = asyncio.create_task(store.wait_until(lambda s: s.navigating, timeout=60))
    await asyncio.sleep(0)
    await device.stop_stream()  # the robot goes quiet; the TCP connection stays up
    with pytest.raises(LinkStale) as info:
        await asyncio.wait_for(waiter, STEP)
    assert info.value.silent_for >= 0.1
    stale = await asyncio.wait_for(anext(events), STEP)
    assert isinstance(stale, ev.LinkStaleEvent)
    assert stale.silent_for >= 0.1
    assert link.stats.stale
    assert link.connected
    device.push()
    fresh = await asyncio.wait_for(anext(events), STEP)
    assert isinstance(fresh, ev.LinkRestored)
    assert not link.stats.stale
    await store.wait_until(lambda s: s.time_stamp == device.time_stamp, timeout=STEP)


async def test_stale_when_the_robot_never_sends(device: FakeDevice, links: list[Link]) -> None:
    _link, store = await connect(device, links, stale_timeout=0.05)
    with pytest.raises(LinkStale):
        await store.wait_until(lambda s: True, timeout=STEP)


async def test_slow_subscriber_does_not_hold_back_others(links: list[Link]) -> None:
    connector, link = await in_memory(links, stale_timeout=None)
    store = link.store
    never_read = store.statuses()
    never_read_events = store.events(maxlen=4)
    fast = store.statuses()
    for stamp in range(1, 3001):
        connector.feed(status_frame(stamp, busy_status=stamp % 2))
        if stamp % 1000 == 0:
            assert (await asyncio.wait_for(anext(fast), STEP)).time_stamp == stamp
    assert link.stats.frames == 3000
    assert (await anext(never_read)).time_stamp == 3000
    assert never_read.dropped == 2999
    assert len(never_read_events.buffer) == 4


async def test_close_is_idempotent_bounded_and_clean(device: FakeDevice, links: list[Link]) -> None:
    link, store = await connect(device, links)
    stream = store.statuses()
    send = asyncio.create_task(link.send(Goto(1)))
    await asyncio.wait_for(asyncio.gather(link.close(), link.close()), STEP)
    await link.close()
    await asyncio.gather(send, return_exceptions=True)
    assert link.closed
    assert not link.connected
    with pytest.raises(StopAsyncIteration):
        await anext(stream)
    with pytest.raises(ConnectionLost):
        await link.send(Goto(1))
    await device.wait_for(lambda: not device.clients)


async def test_open_is_idempotent_and_refused_after_close(links: list[Link]) -> None:
    connector, link = await in_memory(links)
    await link.open()
    assert len(connector.attempts) == 1
    await link.close()
    with pytest.raises(GalileoConnectionError, match="closed"):
        await link.open()


async def test_close_while_reconnecting(device: FakeDevice, links: list[Link]) -> None:
    link, store = await connect(device, links, reconnect_initial=0.001, reconnect_max=0.002)
    events = store.events()
    await device.stop()
    assert isinstance(await asyncio.wait_for(anext(events), STEP), ev.ConnectionLostEvent)
    assert not link.connected
    await asyncio.sleep(0.02)  # let several refused attempts happen
    await asyncio.wait_for(link.close(), STEP)
    assert not link.connected
    assert link.stats.reconnects == 0


async def test_open_failure_is_translated() -> None:
    probe = FakeDevice()
    await probe.start()
    await probe.stop()  # nothing listens on this port any more
    store = StatusStore()
    link = open_link(probe.url, store)
    with pytest.raises(GalileoConnectionError) as info:
        await link.open()
    assert isinstance(info.value, ConnectionError)
    assert isinstance(info.value.__cause__, OSError)
    await link.close()


async def test_raw_frames_are_logged_at_debug_only(
    device: FakeDevice, links: list[Link], caplog: pytest.LogCaptureFixture
) -> None:
    link, store = await connect(device, links)
    with caplog.at_level(logging.INFO, logger="galileo_async"):
        device.push()
        await store.wait_until(lambda s: s.time_stamp == 1, timeout=STEP)
    assert not [r for r in caplog.records if r.name == "galileo_async.transports.frames"]
    with caplog.at_level(logging.DEBUG, logger="galileo_async.transports.frames"):
        device.push()
        await store.wait_until(lambda s: s.time_stamp == 2, timeout=STEP)
        await link.send(Goto(3))
    frames = [r.getMessage() for r in caplog.records if r.name == "galileo_async.transports.frames"]
    assert any(m.startswith("rx cd eb d7 55") for m in frames)
    assert any(m.startswith("tx cd eb d7 02 67 03") for m in frames)


def test_open_link_url_forms(monkeypatch: pytest.MonkeyPatch) -> None:
    store = StatusStore()
    assert isinstance(open_link("socket://[::1]:4000", store).channel, StreamChannel)
    assert isinstance(open_link("/dev/ttyUSB0", store, baudrate=57600).channel, StreamChannel)
    for bad in ("socket://host", "socket://:12", "socket://h:99999"):
        with pytest.raises(InvalidArgument):
            open_link(bad, store)
    with pytest.raises(InvalidArgument):
        open_link("/dev/ttyUSB0", store, baudrate=0)
    with pytest.raises(InvalidArgument):
        open_link("socket://h:1", store, stale_timeout=0)
    monkeypatch.setitem(sys.modules, "galileo_async.ros", None)
    with pytest.raises(GalileoConnectionError, match="ROS"):
        open_link("ros://127.0.0.1:11311", store)


async def test_a_link_keeps_its_loops_clock() -> None:
    """One clock per link: asyncio's own (time.monotonic, called directly), else the loop's."""
    from galileo_async.testing import VirtualClock

    connector = MemoryConnector()
    link = Link(StreamChannel(connector), StatusStore())
    await link.open()
    assert link.stats.clock is time.monotonic
    await link.close()
    clock = VirtualClock.install()
    try:
        virtual = Link(StreamChannel(MemoryConnector()), StatusStore())
        await virtual.open()
        loop = asyncio.get_running_loop()
        assert virtual.stats.clock() == loop.time()
        await asyncio.sleep(3600)  # virtual: the link's clock went with it
        assert virtual.stats.clock() == loop.time()
        await virtual.close()
    finally:
        clock.release()


async def test_sim_url_owns_the_simulator(monkeypatch: pytest.MonkeyPatch) -> None:
    connector = MemoryConnector()
    made: list[Any] = []

    class FakeSimulator:
        def __init__(self, url: str) -> None:
            self.url, self.closed = url, False

        @classmethod
        def named(cls, url: str) -> None:
            return None  # a URL describing a new simulator

        @classmethod
        def from_url(cls, url: str) -> FakeSimulator:
            made.append(cls(url))
            return made[-1]  # type: ignore[no-any-return]

        def connector(self) -> MemoryConnector:
            return connector

        async def close(self) -> None:
            self.closed = True

    module = types.ModuleType("galileo_async.sim")
    module.Simulator = FakeSimulator  # type: ignore[attr-defined]
    monkeypatch.setitem(sys.modules, "galileo_async.sim", module)
    link = open_link("sim://?speed=20", StatusStore(), baudrate=115200)
    assert isinstance(link.channel, StreamChannel)
    assert link.channel.simulator is made[0]
    assert made[0].url == "sim://?speed=20"
    await link.open()
    connector.feed(status_frame(1))
    assert link.store.status is not None
    await link.close()
    assert made[0].closed


# --- silent peers (stale_reconnect) -------------------------------------------------------


async def test_silent_tcp_peer_is_given_up_and_reconnected(
    device: FakeDevice, links: list[Link]
) -> None:
    link, store = await connect(device, links, stale_timeout=0.05, stale_reconnect=3)
    events = store.events()
    device.start_stream(0.01)
    await store.wait_until(lambda s: (s.time_stamp or 0) >= 3, timeout=STEP)
    await device.stop_stream()  # the robot goes quiet; its TCP connection stays open
    assert isinstance(await asyncio.wait_for(anext(events), STEP), ev.LinkStaleEvent)
    lost = await asyncio.wait_for(anext(events), STEP)
    assert isinstance(lost, ev.ConnectionLostEvent)
    assert "no valid status frame" in lost.reason
    assert link.stats.last_frame_at is not None
    assert time.monotonic() - link.stats.last_frame_at >= 3 * 0.05
    # The old connection was closed from our side and a new one accepted.
    await device.wait_for(lambda: device.connections == 2 and len(device.clients) == 1)
    device.push()
    assert isinstance(await asyncio.wait_for(anext(events), STEP), ev.ConnectionRestored)
    assert link.stats.reconnects == 1
    await store.wait_until(lambda s: s.time_stamp == device.time_stamp, timeout=STEP)
    assert not link.stats.stale
    await link.send(Goto(5))
    await device.wait_for(lambda: Goto(5) in device.commands)


async def test_socket_links_turn_tcp_keepalive_on(device: FakeDevice, links: list[Link]) -> None:
    link, _ = await connect(device, links)
    assert isinstance(link.channel, StreamChannel)
    transport = link.channel.transport
    assert transport is not None
    sock = transport.get_extra_info("socket")
    assert sock.getsockopt(socket.SOL_SOCKET, socket.SO_KEEPALIVE) != 0
    if hasattr(socket, "TCP_KEEPIDLE"):  # Linux: short timers, not the 2-hour default
        assert sock.getsockopt(socket.IPPROTO_TCP, socket.TCP_KEEPIDLE) == KEEPALIVE_IDLE
        assert sock.getsockopt(socket.IPPROTO_TCP, socket.TCP_KEEPINTVL) == KEEPALIVE_INTERVAL
        assert sock.getsockopt(socket.IPPROTO_TCP, socket.TCP_KEEPCNT) == KEEPALIVE_COUNT


async def test_socket_links_read_into_their_loops_read_buffer(
    device: FakeDevice, links: list[Link]
) -> None:
    link, store = await connect(device, links)
    assert isinstance(link.channel, StreamChannel)
    assert isinstance(link.channel._protocol, asyncio.BufferedProtocol)
    assert link.channel._protocol.get_buffer(-1) is _read_buffer(asyncio.get_running_loop())[1]
    # A burst over three read buffers, split mid-frame, then a single frame.
    burst = b"".join(status_frame(stamp) for stamp in range(1, 201))
    assert len(burst) > 2 * READ_SIZE
    device.push_raw(burst[:1000])
    device.push_raw(burst[1000:])
    await store.wait_until(lambda s: s.time_stamp == 200, timeout=STEP)
    stream = store.statuses()
    assert (await anext(stream)).time_stamp == 200
    device.time_stamp = 200
    device.push()
    assert (await asyncio.wait_for(anext(stream), STEP)).time_stamp == 201
    assert (link.stats.frames, link.stats.lost_frames, link.stats.resyncs) == (201, 0, 0)
    assert link.stats.bytes_received == len(burst) + len(status_frame(201))


async def test_links_of_one_loop_share_a_read_buffer_and_keep_their_own_partial_frames(
    links: list[Link],
) -> None:
    _, link_a = await in_memory(links)
    _, link_b = await in_memory(links)
    protocol_a, protocol_b = link_a.channel._protocol, link_b.channel._protocol
    assert protocol_a is not None
    assert protocol_b is not None
    assert protocol_a.get_buffer(-1) is protocol_b.get_buffer(-1)

    def read(protocol: asyncio.BufferedProtocol, data: bytes) -> None:
        # What a socket transport does per read: into the protocol's buffer, then notify.
        view = protocol.get_buffer(-1)
        view[: len(data)] = data
        protocol.buffer_updated(len(data))

    frame_a, frame_b = status_frame(7, power=11.5), status_frame(40, power=22.5)
    read(protocol_a, frame_a[:50])
    read(protocol_b, frame_b[:30])
    # b's bytes in between overwrote the buffer: a's held-back half must be a copy.
    read(protocol_a, frame_a[50:] + status_frame(8, power=12.5))
    read(protocol_b, frame_b[30:])
    assert (link_a.stats.frames, link_a.stats.lost_frames, link_a.stats.resyncs) == (2, 0, 0)
    assert (link_b.stats.frames, link_b.stats.resyncs, link_b.stats.bytes_discarded) == (1, 0, 0)
    assert link_a.stats.bytes_discarded == 0
    assert link_a.store.status is not None
    assert link_b.store.status is not None
    assert (link_a.store.status.time_stamp, link_a.store.status.power) == (8, 12.5)
    assert (link_b.store.status.time_stamp, link_b.store.status.power) == (40, 22.5)


def test_event_loops_in_other_threads_get_read_buffers_of_their_own() -> None:
    async def buffer() -> memoryview:
        return _read_buffer(asyncio.get_running_loop())[1]

    async def twice() -> tuple[memoryview, memoryview]:
        return await buffer(), await buffer()

    first, again = asyncio.run(twice())
    assert first is again
    with concurrent.futures.ThreadPoolExecutor(1) as pool:
        other = pool.submit(asyncio.run, buffer()).result(timeout=STEP)
    assert other is not first
    assert len(other) == len(first) == READ_SIZE


async def test_frames_now_and_then_keep_a_stale_link_connected(links: list[Link]) -> None:
    # Stale between frames (0.05 s > 0.02 s), but never silent for 10 x 0.02 s.
    connector, link = await in_memory(links, stale_timeout=0.02, stale_reconnect=10)
    events = link.store.events()
    for stamp in range(1, 8):
        connector.feed(status_frame(stamp))
        await asyncio.sleep(0.05)
    assert link.connected
    assert len(connector.attempts) == 1
    seen = []
    while (event := await asyncio.wait_for(anext(events), STEP)) is not None:
        seen.append(type(event))
        if len(seen) == 4:
            break
    assert seen == [ev.LinkStaleEvent, ev.LinkRestored, ev.LinkStaleEvent, ev.LinkRestored]


async def test_stale_reconnect_none_stays_stale(links: list[Link]) -> None:
    connector, link = await in_memory(links, stale_timeout=0.02, stale_reconnect=None)
    events = link.store.events()
    assert isinstance(await asyncio.wait_for(anext(events), STEP), ev.LinkStaleEvent)
    await asyncio.sleep(0.2)  # ten stale timeouts: the default factor would have given up
    assert link.connected
    assert link.stats.stale
    assert len(connector.attempts) == 1
    assert not connector.transport.is_closing()


async def test_silent_peer_without_reconnect_closes_the_store(links: list[Link]) -> None:
    connector, link = await in_memory(links, stale_timeout=0.02, stale_reconnect=2, reconnect=False)
    events = link.store.events()
    assert isinstance(await asyncio.wait_for(anext(events), STEP), ev.LinkStaleEvent)
    lost = await asyncio.wait_for(anext(events), STEP)
    assert isinstance(lost, ev.ConnectionLostEvent)
    assert "no valid status frame" in lost.reason
    with pytest.raises(StopAsyncIteration):
        await asyncio.wait_for(anext(events), STEP)
    assert connector.transport.is_closing()  # aborted, not left open
    assert not link.connected
    assert len(connector.attempts) == 1


@pytest.mark.parametrize(
    "options",
    [
        {"stale_reconnect": 0.5},
        {"stale_reconnect": float("nan")},
        {"drain_timeout": 0},
        {"max_queued_commands": 0},
        {"max_queued_commands": 1.5},
        {"max_queued_commands": True},
    ],
)
def test_bad_health_and_queue_options_are_refused(options: dict[str, Any]) -> None:
    name = next(iter(options))
    with pytest.raises(InvalidArgument, match=name):
        Link(StreamChannel(MemoryConnector()), StatusStore(), **options)


# --- flow control and the bounded queue ----------------------------------------------------


class BufferingTransport(RecordingTransport):
    """Reports ``buffered`` unsent bytes; a write may stay buffered for ``hold`` seconds."""

    def __init__(self, loop: asyncio.AbstractEventLoop, protocol: asyncio.Protocol) -> None:
        super().__init__(loop, protocol)
        self.buffered = 0
        self.hold: float | None = None  # a slow peer: each write stays buffered this long
        self.overlapping: list[bytes] = []  # writes made while earlier bytes were still buffered
        self.polled = asyncio.Event()
        self._drains: list[asyncio.TimerHandle] = []

    def get_write_buffer_size(self) -> int:
        self.polled.set()
        return self.buffered

    def write(self, data: bytes | bytearray | memoryview) -> None:
        if self.buffered:
            self.overlapping.append(bytes(data))
        super().write(data)
        if self.hold is not None:
            self.buffered += len(data)
            self._drains.append(self.loop.call_later(self.hold, self.drain))

    def drain(self) -> None:
        """The peer took everything."""
        self.buffered = 0

    def close(self) -> None:
        for handle in self._drains:
            handle.cancel()
        super().close()


class BufferingConnector(MemoryConnector):
    """A MemoryConnector whose transports are BufferingTransports."""

    async def __call__(
        self, loop: asyncio.AbstractEventLoop, factory: Callable[[], asyncio.Protocol]
    ) -> tuple[asyncio.BaseTransport, asyncio.Protocol]:
        self.attempts.append(time.monotonic())
        protocol = factory()
        transport = BufferingTransport(loop, protocol)
        protocol.connection_made(transport)
        self.transports.append(transport)
        return transport, protocol

    @property
    def buffering(self) -> BufferingTransport:
        """The newest transport."""
        transport = self.transports[-1]
        assert isinstance(transport, BufferingTransport)
        return transport


async def buffering(links: list[Link], **options: Any) -> tuple[BufferingTransport, Link]:
    connector = BufferingConnector()
    link = Link(StreamChannel(connector), StatusStore(), stale_timeout=None, **options)
    links.append(link)
    await link.open()
    return connector.buffering, link


async def test_each_write_waits_for_an_empty_transport_buffer(links: list[Link]) -> None:
    transport, link = await buffering(links, min_command_interval=0)
    transport.hold = 0.02
    commands = [Goto(i) for i in range(4)]
    await asyncio.wait_for(asyncio.gather(*(link.send(c) for c in commands)), STEP)
    assert [data for _, data in transport.writes] == [encode(c) for c in commands]
    assert transport.overlapping == []  # never flushed back to back after a stall
    times = [t for t, _ in transport.writes]
    assert all(b - a >= 0.02 for a, b in itertools.pairwise(times))


async def test_a_stalled_transport_delays_the_write_until_it_drains(
    links: list[Link],
) -> None:
    transport, link = await buffering(links)
    transport.buffered = 10
    transport.polled.clear()
    send = asyncio.create_task(link.send(Goto(1)))
    for _ in range(3):  # the writer keeps looking without writing
        await asyncio.wait_for(transport.polled.wait(), STEP)
        transport.polled.clear()
    assert not send.done()
    assert transport.writes == []
    transport.drain()
    await asyncio.wait_for(send, STEP)
    assert [data for _, data in transport.writes] == [encode(Goto(1))]


async def test_a_stuck_transport_fails_the_queued_sends(links: list[Link]) -> None:
    transport, link = await buffering(links, drain_timeout=0.05)
    transport.buffered = 10
    started = time.monotonic()
    results = await asyncio.wait_for(
        asyncio.gather(link.send(Goto(1)), link.send(Goto(2)), return_exceptions=True), STEP
    )
    assert time.monotonic() - started >= 0.05
    for result in results:
        assert isinstance(result, GalileoConnectionError)
        assert "10 unsent bytes" in str(result)
    assert transport.writes == []
    assert link.connected  # the link itself stays up; the stale watchdog judges the peer
    transport.drain()
    await asyncio.wait_for(link.send(Goto(3)), STEP)
    assert [data for _, data in transport.writes] == [encode(Goto(3))]


async def test_a_full_queue_makes_send_wait_in_order(links: list[Link]) -> None:
    transport, link = await buffering(links, max_queued_commands=2, drain_timeout=60)
    transport.buffered = 1  # nothing gets written for now
    sends = [asyncio.create_task(link.send(Goto(i))) for i in range(5)]
    for _ in range(3):
        await asyncio.sleep(0)
    assert [entry.command for entry in link.queue.entries] == [Goto(0), Goto(1)]
    sends[2].cancel()  # a sender waiting for room gives up
    sends[0].cancel()  # a queued sender gives up: its place goes to the next in line
    for _ in range(3):
        await asyncio.sleep(0)
    assert [entry.command for entry in link.queue.entries] == [Goto(1), Goto(3)]
    transport.drain()
    await asyncio.wait_for(asyncio.gather(*sends[3:], sends[1]), STEP)
    assert [data for _, data in transport.writes] == [encode(Goto(i)) for i in (1, 3, 4)]
    assert sends[0].cancelled()
    assert sends[2].cancelled()


async def test_senders_waiting_for_room_fail_when_the_link_drops(links: list[Link]) -> None:
    transport, link = await buffering(links, max_queued_commands=1, reconnect=False)
    transport.buffered = 1
    sends = [asyncio.create_task(link.send(Goto(i))) for i in range(3)]
    for _ in range(3):
        await asyncio.sleep(0)
    transport.lose(OSError("unplugged"))
    for send in sends:
        with pytest.raises(ConnectionLost):
            await asyncio.wait_for(send, STEP)
    assert transport.writes == []


async def test_close_fails_senders_waiting_for_room(links: list[Link]) -> None:
    transport, link = await buffering(links, max_queued_commands=1)
    transport.buffered = 1
    sends = [asyncio.create_task(link.send(Goto(i))) for i in range(3)]
    for _ in range(3):
        await asyncio.sleep(0)
    await asyncio.wait_for(link.close(), STEP)
    for send in sends:
        with pytest.raises(ConnectionLost, match="closed"):
            await asyncio.wait_for(send, STEP)
    assert transport.writes == []


class RecordingSink:
    """A StatusSink that only records what the link reports (no StatusStore involved)."""

    def __init__(self) -> None:
        self.calls: list[str] = []
        self.changed = asyncio.Event()

    def record(self, call: str) -> None:
        self.calls.append(call)
        self.changed.set()

    async def wait_for(self, call: str, count: int = 1) -> None:
        async def until() -> None:
            while self.calls.count(call) < count:
                self.changed.clear()
                await self.changed.wait()

        await asyncio.wait_for(until(), STEP)

    def update(self, status: GalileoStatus) -> None:
        self.record(f"update {status.time_stamp}")

    def link_changed(self, state: LinkState, error: GalileoConnectionError | None) -> None:
        self.record(f"{state.name} {type(error).__name__}")

    def close(self) -> None:
        self.record("close")


async def test_a_link_feeds_any_status_sink(links: list[Link]) -> None:
    sink, connector = RecordingSink(), MemoryConnector()
    options = {"stale_timeout": 0.05, "stale_reconnect": None, "reconnect_initial": 0.01}
    link = Link(StreamChannel(connector), sink, **options)
    links.append(link)
    await link.open()
    connector.feed(status_frame(1))
    await sink.wait_for("STALE LinkStale")
    connector.feed(status_frame(2))
    connector.transport.lose(None)
    await connector.wait_connects(2)
    connector.feed(status_frame(3))
    await link.close()
    assert sink.calls[:8] == [
        "update 1",
        "STALE LinkStale",
        "UP NoneType",
        "update 2",
        "LOST ConnectionLost",
        "UP NoneType",  # the first frame after the reopen, not the reopen
        "update 3",
        "close",
    ]
    assert sink.calls[-1] == "close"
