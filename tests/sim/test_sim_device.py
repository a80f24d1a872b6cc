"""The simulator served in-process, over TCP and over a pty, decoded as a host would.

In-process connections run on the virtual clock (``@virtual``); TCP and the pty on the real one.
"""

from __future__ import annotations

import asyncio
import contextlib
import os
import sys
from collections.abc import AsyncIterator, Callable
from typing import Any

import pytest

from galileo_async.models import GalileoStatus, StatusLayout
from galileo_async.protocol import LAYOUTS as SERIAL_LAYOUTS
from galileo_async.protocol import StatusDecoder, encode
from galileo_async.protocol import commands as c
from galileo_async.sim import FRAME_RATE, SimConfig, Simulator, Ticker
from galileo_async.testing import VirtualClock
from galileo_async.transitions import at_target

#: The layouts a byte stream carries (the UDP face's are tested in test_sim_udp.py).
LAYOUTS = list(SERIAL_LAYOUTS)
FAST: dict[str, Any] = {"speed": 50.0, "visual_init_time": 0.5, "busy_on_start": 0.2}
TIMEOUT = 5.0


#: Free within this many metres: the simulator lands a goal it drove on its target.
ARRIVED = 0.01


def arrived(status: GalileoStatus) -> bool:
    """Free within 1 cm of the target: where the simulator ends a goal it drove."""
    return at_target(status, ARRIVED)


class Host(asyncio.Protocol):
    """A minimal host: decodes the status stream and lets tests wait on it."""

    def __init__(self, layout: StatusLayout | None = None) -> None:
        self.decoder = StatusDecoder(layout)
        self.statuses: list[GalileoStatus] = []
        self.received = 0
        self.raw = bytearray()
        self.transport: asyncio.BaseTransport | None = None
        self._changed = asyncio.Event()
        self.lost: asyncio.Future[Exception | None] = asyncio.get_running_loop().create_future()

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        self.transport = transport

    def data_received(self, data: bytes) -> None:
        self.received += len(data)
        self.raw += data
        self.statuses += self.decoder.feed(data)
        self._changed.set()

    def connection_lost(self, exc: Exception | None) -> None:
        if not self.lost.done():
            self.lost.set_result(exc)
        self._changed.set()

    def send(self, *commands: c.Command) -> None:
        """Write the commands in ONE write."""
        assert isinstance(self.transport, asyncio.WriteTransport)
        self.transport.write(b"".join(encode(command) for command in commands))

    async def wait_for(
        self, predicate: Callable[[GalileoStatus], bool], timeout: float = TIMEOUT
    ) -> GalileoStatus:
        async def waiting() -> GalileoStatus:
            seen = 0
            while True:
                for status in self.statuses[seen:]:
                    if predicate(status):
                        return status
                seen = len(self.statuses)
                if self.lost.done():
                    raise ConnectionError("stream ended")
                self._changed.clear()
                await self._changed.wait()

        return await asyncio.wait_for(waiting(), timeout)

    async def bytes_received(self, count: int) -> None:
        async def waiting() -> None:
            while self.received < count:
                self._changed.clear()
                await self._changed.wait()

        await asyncio.wait_for(waiting(), TIMEOUT)

    async def frames(self, count: int) -> list[GalileoStatus]:
        target = len(self.statuses) + count
        await self.wait_for(lambda _: len(self.statuses) >= target)
        return self.statuses[-count:]


@pytest.fixture
async def virtual_clock() -> AsyncIterator[VirtualClock]:
    """The test's loop on a virtual clock (galileo_async.testing), the real one again after."""
    clock = VirtualClock.install()
    yield clock
    clock.release()


#: The test runs on the virtual clock: exact loop times, no real waiting.
virtual = pytest.mark.usefixtures("virtual_clock")


@pytest.fixture
async def sim() -> AsyncIterator[Simulator]:
    simulator = Simulator(**FAST)
    yield simulator
    await simulator.close()


async def connect(simulator: Simulator, layout: StatusLayout | None = None) -> Host:
    loop = asyncio.get_running_loop()
    _, protocol = await simulator.connector()(loop, lambda: Host(layout))
    assert isinstance(protocol, Host)
    return protocol


async def start_navigation(host: Host) -> None:
    host.send(c.StartNavigation())
    await host.wait_for(lambda s: s.visual_initialised and not s.is_busy)


# ---------------------------------------------------------------- in-process connector
@virtual
@pytest.mark.parametrize("layout", LAYOUTS)
async def test_connector_stream_in_every_layout(layout: StatusLayout) -> None:
    async with Simulator(layout=layout, **FAST) as simulator:
        host = await connect(simulator)
        frames = await host.frames(20)
        assert host.decoder.stats.layout is layout
        assert host.decoder.stats.bytes_discarded == 0
        assert all(s.layout is layout for s in frames)
        assert frames[0].target_status == -1
        assert frames[0].target_num_id == -1
        if layout in (StatusLayout.V1, StatusLayout.V2):
            stamps = [s.time_stamp for s in host.statuses]
            assert stamps[0] == 1
            assert stamps == list(range(1, len(stamps) + 1))
        host.send(c.StartNavigation())
        await host.wait_for(lambda s: s.visual_initialised and not s.is_busy)
        host.send(c.Goto(0))
        await host.wait_for(lambda s: s.target_num_id == 0 and s.target_status == 1)
        done = await host.wait_for(lambda s: s.target_status == 0)
        assert arrived(done)


@virtual
async def test_speed_scales_frame_rate(sim: Simulator) -> None:
    loop = asyncio.get_running_loop()
    host = await connect(sim)
    await host.frames(1)
    started, first = loop.time(), len(host.statuses)
    await host.frames(300)  # 6 simulated seconds at speed 50
    elapsed = loop.time() - started
    rate = (len(host.statuses) - first) / elapsed
    assert rate == pytest.approx(FRAME_RATE * FAST["speed"], rel=1e-6)  # per loop second
    assert sim.state.time == pytest.approx(sim.state.time_stamp / 30)


@virtual
async def test_reconnect_gets_fresh_stream_from_same_robot(sim: Simulator) -> None:
    first = await connect(sim)
    await start_navigation(first)
    first.send(c.AddTarget(1.0, 1.0))
    last_stamp = (await first.frames(3))[-1].time_stamp
    assert first.transport is not None
    first.transport.close()
    await asyncio.wait_for(first.lost, TIMEOUT)
    assert sim.state.connections == 0
    second = await connect(sim)
    status = (await second.frames(3))[0]
    assert status.nav_status == 1
    assert status.visual_initialised
    assert status.time_stamp is not None
    assert last_stamp is not None
    assert status.time_stamp > last_stamp  # the robot's counter kept running
    assert len(sim.state.targets) == len(SimConfig().targets) + 1
    second.send(c.Goto(len(SimConfig().targets)))
    await second.wait_for(lambda s: arrived(s) and s.target_num_id == 6, timeout=10)


@virtual
async def test_concatenated_commands_lose_the_middle_ones(sim: Simulator) -> None:
    host = await connect(sim)
    await host.frames(1)
    host.send(*(c.AddTarget(float(i), 0.5) for i in range(4)))
    await host.frames(2)
    added = sim.state.targets[len(SimConfig().targets) :]
    assert added == ((0.0, 0.5), (3.0, 0.5))
    assert sim.state.stats.commands_lost == 2


@virtual
async def test_document_firmware_keeps_concatenated_commands() -> None:
    async with Simulator(firmware="document", **FAST) as simulator:
        host = await connect(simulator)
        host.send(*(c.AddTarget(float(i), 0.5) for i in range(4)))
        await host.frames(2)
        assert len(simulator.state.targets) == len(SimConfig().targets) + 4


@virtual
async def test_busy_commands_wait(sim: Simulator) -> None:
    host = await connect(sim)
    await start_navigation(host)
    sim.model.set_busy(2.0)
    await host.wait_for(lambda s: s.is_busy)
    host.send(c.Goto(0))
    await host.frames(5)
    assert sim.state.pending_commands == 1
    assert host.statuses[-1].target_status == -1
    status = await host.wait_for(lambda s: s.target_status == 1)
    assert status.busy_status == 0


@virtual
async def test_host_shutdown_stops_frames_and_connections(sim: Simulator) -> None:
    host = await connect(sim)
    await host.frames(2)
    host.send(c.ShutdownHost())
    await asyncio.wait_for(host.lost, TIMEOUT)
    count = len(host.statuses)
    assert sim.state.shutdown
    assert not sim.accepting
    with pytest.raises(ConnectionRefusedError):
        await connect(sim)
    stamp = sim.state.time_stamp
    await asyncio.sleep(0.05)  # a window in which a live robot sends 75 frames
    assert sim.state.time_stamp == stamp
    assert len(host.statuses) == count


@virtual
async def test_shutdown_queued_while_busy_takes_effect_later(sim: Simulator) -> None:
    host = await connect(sim)
    await start_navigation(host)
    sim.model.set_busy(1.0)
    await host.wait_for(lambda s: s.is_busy)
    host.send(c.ShutdownHost())
    await host.frames(3)
    assert not host.lost.done()
    await asyncio.wait_for(host.lost, TIMEOUT)
    assert sim.state.shutdown
    assert not sim.accepting


@virtual
async def test_shared_ticker_drives_many_robots() -> None:
    ticker = Ticker(speed=50.0)
    simulators = [Simulator(ticker=ticker, seed=i, **FAST) for i in range(20)]
    try:
        hosts = [await connect(simulator) for simulator in simulators]
        await asyncio.gather(*(host.frames(10) for host in hosts))
        assert ticker.running
        stamps = {simulator.state.time_stamp for simulator in simulators}
        assert max(stamps) - min(stamps) <= 10  # one clock: they advance together
    finally:
        for simulator in simulators:
            await simulator.close()
    assert not ticker.running
    with pytest.raises(ValueError, match="speed"):
        Simulator(ticker=ticker, speed=2.0)


@virtual
async def test_from_url() -> None:
    simulator = Simulator.from_url("sim://?speed=40&layout=v1_charge&firmware=document&seed=1")
    assert simulator.config.layout is StatusLayout.V1_CHARGE
    assert simulator.config.firmware == "document"
    assert simulator.config.speed == 40
    async with simulator:
        host = await connect(simulator)
        await host.frames(3)
        assert host.decoder.layout is StatusLayout.V1_CHARGE


# ---------------------------------------------------------------- faults
@virtual
async def test_dropped_frames_show_as_time_stamp_gaps() -> None:
    async with Simulator(drop=0.2, seed=4, **FAST) as simulator:
        host = await connect(simulator)
        await host.frames(300)
        stats, decoded = simulator.state.stats, host.decoder.stats
        assert stats.frames_dropped > 20
        # Drops after the last received frame are not visible yet.
        assert stats.frames_dropped - 10 <= decoded.lost_frames <= stats.frames_dropped
        assert decoded.bytes_discarded == 0


@virtual
async def test_garbage_is_counted_by_the_decoder() -> None:
    async with Simulator(garbage=0.3, seed=5, **FAST) as simulator:
        host = await connect(simulator)
        await host.frames(200)
        await host.frames(1)
        stats = simulator.state.stats
        assert stats.garbage_bytes > 100
        assert host.decoder.stats.bytes_discarded == stats.garbage_bytes
        assert host.decoder.stats.lost_frames == 0


@virtual
async def test_bit_flips_corrupt_frames() -> None:
    count = 100
    async with (
        Simulator(bitflip=1.0, seed=6, **FAST) as flipped,
        Simulator(seed=6, **FAST) as clean,
    ):
        noisy_host, clean_host = await connect(flipped), await connect(clean)
        await noisy_host.bytes_received(count * 89)
        await clean_host.bytes_received(count * 89)
        noisy, reference = noisy_host.raw[: count * 89], clean_host.raw[: count * 89]
        # An idle robot sends the same frames each run: the streams differ by exactly one
        # bit per frame.
        differing = sum(bin(a ^ b).count("1") for a, b in zip(noisy, reference, strict=True))
        assert differing == count
        assert flipped.state.stats.bit_flips >= count
        assert StatusDecoder().feed(noisy) != StatusDecoder().feed(reference)


@virtual
async def test_disconnect_after_simulated_seconds() -> None:
    async with Simulator(disconnect_after=2.0, **FAST) as simulator:
        host = await connect(simulator)
        await asyncio.wait_for(host.lost, TIMEOUT)
        assert len(host.statuses) == 60  # 2 s at 30 frames per simulated second
        again = await connect(simulator)  # a reconnecting host is served again
        await asyncio.wait_for(again.lost, TIMEOUT)
        assert simulator.state.stats.disconnects == 2


@virtual
async def test_planner_abort_over_the_wire() -> None:
    async with Simulator(planner_abort="next", **FAST) as simulator:
        host = await connect(simulator)
        await start_navigation(host)
        host.send(c.Goto(1))  # 5 m away
        await host.wait_for(lambda s: s.target_status == 1)
        done = await host.wait_for(lambda s: s.target_status == 0)
        assert done.target_distance is not None
        assert done.target_distance > 1.0


# ---------------------------------------------------------------- TCP
async def test_tcp_serves_several_clients(sim: Simulator) -> None:
    loop = asyncio.get_running_loop()
    server = await sim.serve_tcp()
    host, port = server.sockets[0].getsockname()[:2]
    assert host == "127.0.0.1"
    _, first = await loop.create_connection(Host, host, port)
    _, second = await loop.create_connection(Host, host, port)
    assert isinstance(first, Host)
    assert isinstance(second, Host)
    await first.frames(3)
    await second.frames(3)
    assert sim.state.connections == 2
    first.send(c.StartNavigation())
    await second.wait_for(lambda s: s.visual_initialised and not s.is_busy)
    second.send(c.Goto(2))
    await first.wait_for(lambda s: s.target_num_id == 2 and s.target_status == 1)
    assert arrived(await first.wait_for(lambda s: s.target_status == 0, timeout=10))
    await sim.close()
    await asyncio.wait_for(first.lost, TIMEOUT)
    await asyncio.wait_for(second.lost, TIMEOUT)
    assert not server.is_serving()


@pytest.mark.parametrize("layout", LAYOUTS)
async def test_tcp_layouts_and_shutdown(layout: StatusLayout) -> None:
    loop = asyncio.get_running_loop()
    async with Simulator(layout=layout, **FAST) as simulator:
        server = await simulator.serve_tcp("127.0.0.1", 0)
        port = server.sockets[0].getsockname()[1]
        _, host = await loop.create_connection(Host, "127.0.0.1", port)
        assert isinstance(host, Host)
        await host.frames(5)
        assert host.decoder.layout is layout
        host.send(c.ShutdownHost())
        await asyncio.wait_for(host.lost, TIMEOUT)
        assert not server.is_serving()
        with pytest.raises(ConnectionRefusedError):
            await loop.create_connection(Host, "127.0.0.1", port)


async def test_tcp_concatenated_commands_lose_the_middle_ones(sim: Simulator) -> None:
    loop = asyncio.get_running_loop()
    server = await sim.serve_tcp()
    _, host = await loop.create_connection(Host, *server.sockets[0].getsockname()[:2])
    assert isinstance(host, Host)
    await host.frames(1)
    host.send(*(c.AddTarget(float(i), 0.5) for i in range(10)))
    await host.frames(3)
    assert sim.state.targets[len(SimConfig().targets) :] == ((0.0, 0.5), (9.0, 0.5))
    assert sim.state.stats.commands_lost == 8


@virtual
async def test_state_view_and_refusals_after_close() -> None:
    simulator = Simulator(targets=((1.0, 1.0),), dock=(2.0, 2.0), patrol_dwell=4.0, **FAST)
    state = simulator.state
    assert state.targets == ((1.0, 1.0),)
    assert state.dock == (2.0, 2.0)
    assert state.patrol_dwell == 4.0
    assert state.greeting is True
    assert state.time == 0.0
    assert state.time_stamp == 0
    assert state.pose.x == 0.0
    host = await connect(simulator)
    host.send(c.Greeting(False))
    await host.frames(2)
    assert state.greeting is False
    assert state.commands_handled == 1
    assert state.connections == 1
    assert state.status.time_stamp == state.time_stamp
    await simulator.close()
    await asyncio.wait_for(host.lost, TIMEOUT)
    await simulator.close()  # idempotent
    assert not simulator.accepting
    with pytest.raises(ConnectionRefusedError):
        await simulator.serve_tcp()
    with pytest.raises(ConnectionRefusedError):
        simulator.open_pty()
    with pytest.raises(ConnectionRefusedError):
        await connect(simulator)


# ---------------------------------------------------------------- pty
needs_pty = pytest.mark.skipif(sys.platform == "win32", reason="pseudo-terminals are POSIX only")


@needs_pty
async def test_disconnect_fault_spares_the_pty() -> None:
    loop = asyncio.get_running_loop()
    async with Simulator(disconnect_after=1.0, **FAST) as simulator:
        path = simulator.open_pty()
        stream = await connect(simulator)
        with opened(path) as fd:
            host = Host()
            await attach_pty(fd, host)
            try:
                await asyncio.wait_for(stream.lost, TIMEOUT)
                await host.frames(60)  # the pty keeps going well past the cut
                assert not host.lost.done()
            finally:
                loop.remove_reader(fd)


@contextlib.contextmanager
def opened(path: str) -> Any:
    fd = os.open(path, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
    try:
        yield fd
    finally:
        os.close(fd)


async def attach_pty(fd: int, host: Host) -> None:
    loop = asyncio.get_running_loop()

    def readable() -> None:
        try:
            data = os.read(fd, 4096)
        except BlockingIOError:
            return
        except OSError as exc:  # the device went away
            loop.remove_reader(fd)
            host.connection_lost(exc)
            return
        if not data:
            loop.remove_reader(fd)
            host.connection_lost(None)
            return
        host.data_received(data)

    loop.add_reader(fd, readable)


@needs_pty
@pytest.mark.parametrize("layout", LAYOUTS)
async def test_pty_stream_and_commands(layout: StatusLayout) -> None:
    loop = asyncio.get_running_loop()
    async with Simulator(layout=layout, **FAST) as simulator:
        path = simulator.open_pty()
        with opened(path) as fd:
            host = Host()
            await attach_pty(fd, host)
            try:
                await host.frames(10)
                assert host.decoder.layout is layout
                os.write(fd, encode(c.StartNavigation()))
                await host.wait_for(lambda s: s.visual_initialised and not s.is_busy)
                os.write(fd, encode(c.Goto(0)))
                done = await host.wait_for(lambda s: arrived(s) and s.target_num_id == 0)
                assert arrived(done)
            finally:
                loop.remove_reader(fd)


@needs_pty
async def test_pty_late_opener_gets_fresh_frames_and_shutdown_removes_device() -> None:
    loop = asyncio.get_running_loop()
    async with Simulator(**FAST) as simulator:
        path = simulator.open_pty()
        watcher = await connect(simulator)  # frames flow to the pty meanwhile, unread
        await watcher.frames(600)
        with opened(path) as fd:
            host = Host()
            await attach_pty(fd, host)
            try:
                first = (await host.frames(1))[0]
                assert first.time_stamp is not None
                # At most the small backlog is stale, never the whole history.
                assert first.time_stamp > simulator.state.time_stamp - 100
                os.write(fd, encode(c.ShutdownHost()))
                await asyncio.wait_for(host.lost, TIMEOUT)
            finally:
                loop.remove_reader(fd)
        assert simulator.state.shutdown
