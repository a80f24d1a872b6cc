"""udp:// against the simulator's UDP face and plain sockets on loopback (docs/protocol.md §7)."""

from __future__ import annotations

import asyncio
import contextlib
import socket
import subprocess
import sys
from collections.abc import AsyncIterator
from typing import Any

import pytest

import galileo_async as galileo
from galileo_async import (
    GoalAborted,
    InvalidArgument,
    LinkStale,
    StatusLayout,
)
from galileo_async.events import LinkRestored, LinkStaleEvent
from galileo_async.links import open_link
from galileo_async.protocol import HEADER, Forward, RawCommand, Stop, encode, encode_status
from galileo_async.sim import Simulator
from galileo_async.transports.udp import REGISTRATION, parse_udp_url
from tests.support.cancel_ways import WAYS, stop_waiting

pytestmark = pytest.mark.timeout(60)

WAIT = 10.0
SPEED = 40.0
TARGETS = ((1.5, 0.0), (30.0, 0.0))


class Peer(asyncio.DatagramProtocol):
    """A plain UDP socket on 127.0.0.1: records what it receives, answers its last sender."""

    def __init__(self) -> None:
        self.datagrams: list[bytes] = []
        self.senders: list[Any] = []
        self.last_sender: Any = None
        self.transport: asyncio.DatagramTransport | None = None
        self.arrived = asyncio.Event()

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        self.transport = transport  # type: ignore[assignment]

    def datagram_received(self, data: bytes, addr: Any) -> None:
        self.datagrams.append(data)
        self.senders.append(addr)
        self.last_sender = addr
        self.arrived.set()

    async def next(self) -> bytes:
        """The next datagram (waits for one)."""
        count = len(self.datagrams)
        while len(self.datagrams) == count:
            self.arrived.clear()
            await asyncio.wait_for(self.arrived.wait(), WAIT)
        return self.datagrams[count]

    def answer(self, data: bytes) -> None:
        assert self.transport is not None
        self.transport.sendto(data, self.last_sender)

    @property
    def port(self) -> int:
        assert self.transport is not None
        return int(self.transport.get_extra_info("sockname")[1])


@contextlib.asynccontextmanager
async def peer(remote: tuple[str, int] | None = None) -> AsyncIterator[Peer]:
    """A Peer bound to a free loopback port (sending to ``remote`` if given)."""
    loop = asyncio.get_running_loop()
    transport, protocol = await loop.create_datagram_endpoint(
        Peer, local_addr=("127.0.0.1", 0), remote_addr=remote
    )
    try:
        yield protocol
    finally:
        transport.close()


@contextlib.asynccontextmanager
async def robot_on_udp(
    robot_options: dict[str, Any] | None = None, **sim_options: Any
) -> AsyncIterator[tuple[Simulator, galileo.Robot, Any]]:
    """A simulator serving UDP on 127.0.0.1 and a Robot on udp:// to it (and the face)."""
    options: dict[str, Any] = {"speed": SPEED, "targets": TARGETS, **sim_options}
    async with Simulator(**options) as sim:
        face = await sim.serve_udp()
        url = f"udp://127.0.0.1:{face.address[1]}"
        async with galileo.connect(url, map_targets=len(TARGETS), **(robot_options or {})) as robot:
            yield sim, robot, face


def status_frame(**fields: Any) -> bytes:
    """A 48-byte UDP status frame of an idle robot at 24 V."""
    status = galileo.GalileoStatus(
        layout=StatusLayout.UDP_V2, power=24.0, target_num_id=-1, target_status=-1, **fields
    )
    return encode_status(status)


# --- the URL ---------------------------------------------------------------------------------


def test_url_default_port_and_forms() -> None:
    assert parse_udp_url("udp://10.0.0.5") == ("10.0.0.5", 20001)
    assert parse_udp_url("udp://10.0.0.5:20002") == ("10.0.0.5", 20002)
    assert parse_udp_url("udp://[::1]:7") == ("::1", 7)
    for bad in ("udp://", "udp://host:port", "udp://host:1/path", "udp://host?x=1"):
        with pytest.raises(InvalidArgument):
            parse_udp_url(bad)


async def test_options_checked_before_anything_opens() -> None:
    with pytest.raises(InvalidArgument, match="layout does not apply to udp://"):
        await galileo.connect("udp://127.0.0.1:9", layout="v2")
    with pytest.raises(InvalidArgument, match="stale_timeout"):
        await galileo.connect("udp://127.0.0.1:9", stale_timeout=-1)
    # The portable options a fleet file shares are taken and ignored.
    link = open_link("udp://127.0.0.1:9", _NullSink(), baudrate=9600, connect_timeout=1.0)
    assert repr(link) == "<Link udp://127.0.0.1:9>"
    await link.close()


class _NullSink:
    def update(self, status: object) -> None: ...
    def link_changed(self, state: object, error: object) -> None: ...
    def close(self) -> None: ...


# --- what goes on the wire --------------------------------------------------------------------


async def test_registers_then_sends_one_whole_frame_per_datagram() -> None:
    async with peer() as robot_port:
        url = f"udp://127.0.0.1:{robot_port.port}"
        connecting = asyncio.ensure_future(galileo.connect(url, min_command_interval=0.0))
        try:
            assert await robot_port.next() == REGISTRATION  # before anything else
            robot_port.answer(status_frame())
            robot = await asyncio.wait_for(connecting, WAIT)
        finally:
            connecting.cancel()
        try:
            for command in (Forward(10), Stop(), Forward(20)):
                await robot.send(command)
                assert await robot_port.next() == encode(command)
            assert b"" not in robot_port.datagrams
        finally:
            await robot.close()


async def test_registers_again_when_stale_and_from_a_new_socket_after_giving_up() -> None:
    async with peer() as robot_port:
        url = f"udp://127.0.0.1:{robot_port.port}"
        connecting = asyncio.ensure_future(
            galileo.connect(url, stale_timeout=0.2, stale_reconnect=2.0)
        )
        try:
            await robot_port.next()
            robot_port.answer(status_frame())  # one frame, then silence
            robot = await asyncio.wait_for(connecting, WAIT)
        finally:
            connecting.cancel()
        try:
            assert await robot_port.next() == REGISTRATION  # stale: take the stream back
            assert await robot_port.next() == REGISTRATION  # given up: a new socket
        finally:
            await robot.close()
        assert robot_port.datagrams == [REGISTRATION] * 3
        first, stale, reconnected = robot_port.senders
        assert stale == first
        assert reconnected != first


async def test_a_short_gi_is_refused_before_anything_is_sent() -> None:
    async with robot_on_udp() as (sim, robot, face):
        with pytest.raises(InvalidArgument, match="'gi' payload shorter than 10"):
            await robot.send(RawCommand(b"gi\x00"))
        await robot.forward(10)
        await robot.wait_until(lambda _s: sim.state.status.current_speed_x, timeout=WAIT)
        assert not face.commands_dead  # the vendor's command thread would be dead


async def test_the_simulator_sends_nothing_before_a_datagram() -> None:
    async with Simulator(speed=SPEED) as sim:
        face = await sim.serve_udp()
        await asyncio.sleep(0.05)
        assert face.remote is None
        assert face.frames_sent == 0
        assert sim.state.time > 0  # the robot's clock runs meanwhile


async def test_the_simulator_dies_of_what_kills_the_vendors_service() -> None:
    async with Simulator(speed=SPEED) as sim:
        face = await sim.serve_udp()
        async with peer(face.address) as host:
            assert host.transport is not None
            host.transport.sendto(HEADER + b"\x03gi\x00")  # a short gi: commands stop
            await host.next()  # status still flows
            assert face.commands_dead
            host.transport.sendto(encode(Forward(50)))
            await host.next()
            await host.next()  # a whole tick after the command arrived
            assert face.datagrams == 2
            assert sim.state.commands_handled == 0
            with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as raw:
                raw.sendto(b"", face.address)  # an empty datagram (asyncio sends none): the end
            await asyncio.wait_for(face.wait_closed(), WAIT)


# --- last sender wins -------------------------------------------------------------------------


async def test_another_sender_takes_the_stream_and_the_link_says_so() -> None:
    async with robot_on_udp({"stale_timeout": 0.3}, speed=1.0) as (_sim, robot, face):
        events: list[object] = []

        async def collect() -> None:
            async for event in robot.events():
                if isinstance(event, (LinkStaleEvent, LinkRestored)):
                    events.append(event)
                    if isinstance(event, LinkRestored):
                        return

        collecting = asyncio.create_task(collect())
        waiter = asyncio.create_task(robot.wait_until(lambda _s: False, timeout=WAIT))
        try:
            async with peer(face.address) as thief:
                await asyncio.sleep(0)
                assert thief.transport is not None
                thief.transport.sendto(b"hello")  # any datagram takes the stream
                await thief.next()  # the robot now streams to the thief
                with pytest.raises(LinkStale, match="another host may have taken the UDP channel"):
                    await asyncio.wait_for(waiter, WAIT)
                # Stale, the link registers again and takes the stream back.
                await asyncio.wait_for(collecting, WAIT)
        finally:
            waiter.cancel()
            collecting.cancel()
        assert [type(e) for e in events] == [LinkStaleEvent, LinkRestored]
        assert face.remote[1] != thief.port
        assert robot.link.reconnects == 0


async def test_nothing_listening_is_named_in_the_stale_error() -> None:
    probe = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    probe.bind(("127.0.0.1", 0))
    port = probe.getsockname()[1]
    probe.close()  # nothing listens there now: the kernel answers port unreachable
    async with galileo.connect(
        f"udp://127.0.0.1:{port}", first_status_timeout=None, stale_timeout=0.2
    ) as robot:
        with pytest.raises(LinkStale, match="the robot refused our datagrams"):
            await robot.wait_until(lambda _s: True, timeout=WAIT)


# --- the layouts ------------------------------------------------------------------------------


async def test_the_44_byte_layout() -> None:
    async with robot_on_udp(udp_layout="udp_v1") as (sim, robot, _face):
        assert robot.link.layout is StatusLayout.UDP_V1
        assert robot.status is not None
        assert robot.status.target_distance is None
        await robot.start_navigation(timeout=WAIT)
        await robot.forward(50)
        await robot.wait_until(lambda s: (s.current_pose_x or 0) > 0.2, timeout=WAIT)
        await robot.stop()
        # No distance on this layout: a goal that ends free cannot be told reached from
        # given up, and the goal rule never guesses an arrival.
        with pytest.raises(GoalAborted) as failed:
            await robot.goto(0, timeout=WAIT)
        assert failed.value.distance is None
        assert sim.state.pose.x == pytest.approx(1.5, abs=0.01)  # it did get there


async def test_environment_frames_are_skipped() -> None:
    async with robot_on_udp(env_sensors=True) as (_sim, robot, _face):
        await robot.wait_until(lambda _s: robot.link.frames > 12, timeout=WAIT)
        link = robot.link
        env_bytes = link.bytes_received - 48 * link.frames
        assert env_bytes >= 3 * 36  # received and skipped, not garbage
        assert env_bytes % 36 == 0
        assert link.bytes_discarded == 0


async def test_lost_datagrams_are_only_counted() -> None:
    async with robot_on_udp(drop=0.3, garbage=0.2, seed=1) as (sim, robot, _face):
        await robot.start_navigation(timeout=WAIT)
        result = await robot.goto(0, timeout=WAIT)
        assert result.distance == 0.0
        assert sim.state.stats.frames_dropped > 0
        assert robot.link.bytes_discarded > 0


# --- cancellation -----------------------------------------------------------------------------


@pytest.mark.parametrize("how", WAYS)
async def test_a_cancelled_connect_closes_its_socket(how: str) -> None:
    async with peer() as silent:  # registers us, never answers

        async def opening() -> None:
            async with galileo.connect(f"udp://127.0.0.1:{silent.port}", first_status_timeout=20):
                pytest.fail("nothing answers: connect cannot succeed")

        await stop_waiting(how, opening, 0.3)  # then the autouse fixture finds nothing left
        assert silent.datagrams == [REGISTRATION]


# --- the command line -------------------------------------------------------------------------


def test_cli_status_over_udp() -> None:
    sim = subprocess.Popen(
        [sys.executable, "-m", "galileo_async", "sim", "--udp", "0", "--speed", "20"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert sim.stdout is not None
        url = sim.stdout.readline().strip()
        assert url.startswith("udp://127.0.0.1:")
        result = subprocess.run(
            [sys.executable, "-m", "galileo_async", "-p", url, "status", "--json"],
            capture_output=True,
            text=True,
            timeout=WAIT * 3,
        )
        assert result.returncode == 0, result.stderr
        assert '"layout": "udp_v2"' in result.stdout
    finally:
        sim.terminate()
        sim.communicate(timeout=WAIT)
