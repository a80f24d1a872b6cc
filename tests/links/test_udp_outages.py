"""udp:// through the outages of the robot's UDP service, on the virtual clock (issue 30, item 5).

The simulator's UDP face plays the vendor's system_monitor service: it streams to the source
of the last datagram it received, and a restarted service streams to nobody until a datagram
comes. The link is the real Link over a UdpChannel on 127.0.0.1. Everything runs on one
VirtualClock: on
Linux a loopback datagram is in the receiver's socket buffer when ``sendto`` returns, so the
clock's idle check sees it before time moves on. The link's defaults apply: stale after 1 s
without a frame, given up (LOST, a new socket) after 5 s.
"""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import AsyncIterator
from typing import Any

import pytest

import galileo_async as galileo
from galileo_async import LinkState, TargetStatus
from galileo_async.events import Event
from galileo_async.protocol import Cancel, Command, Goto
from galileo_async.sim import Simulator
from galileo_async.sim.udp import UdpFace
from galileo_async.testing import VirtualClock

pytestmark = pytest.mark.timeout(60)

#: Virtual seconds any single wait may take before it fails.
WAIT = 60.0
#: Target 0 is one metre ahead; target 1 twelve metres (15 s at the simulator's 0.8 m/s).
TARGETS: tuple[tuple[float, float], ...] = ((1.0, 0.0), (12.0, 0.0))
NEAR, FAR = 0, 1
#: The link's defaults: stale_timeout, and stale_reconnect x stale_timeout.
STALE, LOST = 1.0, 5.0


class Bench:
    """A simulated robot serving UDP, a Robot on udp:// to it, and what the robot received."""

    def __init__(self, sim: Simulator, face: UdpFace, clock: VirtualClock) -> None:
        self.sim = sim
        self.face = face
        self.clock = clock
        self.port = face.address[1]
        self.commands: list[Command] = []
        sim.on_command(self.commands.append)

    @property
    def url(self) -> str:
        return f"udp://127.0.0.1:{self.port}"

    async def restart_service(self) -> None:
        """Close the service's socket, then serve a new one on the same port (no reader yet)."""
        self.face.close()
        await asyncio.wait_for(self.face.wait_closed(), WAIT)
        self.face = await self.sim.serve_udp(port=self.port)


@contextlib.asynccontextmanager
async def bench(**options: Any) -> AsyncIterator[tuple[Bench, galileo.Robot]]:
    """A navigating simulated robot on UDP and a connected Robot, on a virtual clock."""
    clock = VirtualClock.install()
    try:
        async with Simulator(targets=TARGETS) as sim:
            sim.model.open_navigation()
            face = await sim.serve_udp()
            setup = Bench(sim, face, clock)
            async with galileo.connect(setup.url, map_targets=len(TARGETS), **options) as robot:
                yield setup, robot
    finally:
        clock.release()


def recorded(robot: galileo.Robot) -> list[str]:
    """The names of ``robot``'s events from now on, in order (a synchronous listener)."""
    names: list[str] = []

    def record(event: Event) -> None:
        names.append(event.name)

    robot.add_event_listener(record)
    return names


def link_events(names: list[str]) -> list[str]:
    return [n for n in names if n.startswith(("Link", "Connection"))]


async def far_goal_working(robot: galileo.Robot) -> None:
    await robot.wait_until(
        lambda s: s.target_num_id == FAR and s.target_status == TargetStatus.WORKING,
        timeout=WAIT,
    )


# --- item 5a: the link comes back UP after any outage -------------------------------------


async def test_up_with_the_first_frame() -> None:
    async with bench() as (_setup, robot):
        # connect() returned on the first frame: the link is UP then, not still connecting.
        assert robot.link_state is LinkState.UP
        assert await robot.wait_link(LinkState.UP, timeout=0.1) is LinkState.UP


async def test_a_service_restart_after_the_link_was_given_up() -> None:
    async with bench() as (setup, robot):
        names = recorded(robot)
        setup.face.close()  # the service stops; nothing answers on its port
        await robot.wait_link(LinkState.LOST, timeout=WAIT)
        await setup.clock.advance(1.5)  # down 6.5 s in all
        await setup.restart_service()
        # The link's next registration reaches the new service, whose frames end the outage.
        await robot.wait_link(LinkState.UP, timeout=WAIT)
        assert link_events(names) == ["LinkStale", "ConnectionLost", "ConnectionRestored"]
        result = await robot.goto(NEAR, timeout=WAIT)  # commands work again
        assert result.target_id == NEAR
        assert setup.face.remote is not None
        assert robot.link.state is LinkState.UP


async def test_a_service_restart_within_the_stale_timeout() -> None:
    async with bench() as (setup, robot):
        names = recorded(robot)
        await setup.restart_service()  # the new service streams to nobody yet
        await robot.wait_link(LinkState.STALE, timeout=WAIT)  # so the link registers again
        await robot.wait_link(LinkState.UP, timeout=WAIT)
        assert link_events(names) == ["LinkStale", "LinkRestored"]
        assert (await robot.goto(NEAR, timeout=WAIT)).target_id == NEAR


async def test_a_freeze_longer_than_the_lost_timeout() -> None:
    async with bench() as (setup, robot):
        names = recorded(robot)
        setup.sim.muted = True  # the service keeps its socket and sends nothing
        await setup.clock.advance(6.5)
        assert robot.link_state is LinkState.LOST  # given up after 5 s, on a new socket since
        setup.sim.muted = False  # 30 frames/s again, to the socket that registered last
        await robot.wait_link(LinkState.UP, timeout=WAIT)
        assert link_events(names) == ["LinkStale", "ConnectionLost", "ConnectionRestored"]
        assert robot.link.reconnects >= 1
        assert (await robot.goto(NEAR, timeout=WAIT)).target_id == NEAR


# --- item 5b: another program takes the stream for a moment --------------------------------


async def test_another_program_takes_the_stream_and_the_goal_goes_on() -> None:
    async with bench() as (setup, robot):
        names = recorded(robot)
        goal = asyncio.create_task(robot.goto(FAR, timeout=WAIT))
        await far_goal_working(robot)
        loop = asyncio.get_running_loop()
        # `galileo status` in another terminal: one datagram, and the stream goes there.
        thief, _ = await loop.create_datagram_endpoint(
            asyncio.DatagramProtocol, remote_addr=("127.0.0.1", setup.port)
        )
        try:
            thief.sendto(b"\xcd\xeb\xd7\x00")
            await robot.wait_link(LinkState.STALE, timeout=WAIT)
            await robot.wait_link(LinkState.UP, timeout=WAIT)  # registered again: back
        finally:
            thief.close()
        result = await asyncio.wait_for(goal, WAIT)
        assert result.target_id == FAR
        assert setup.sim.state.pose.x == pytest.approx(12.0, abs=0.05)
    assert setup.commands == [Goto(FAR)]  # no i 2: the goal was never cancelled
    assert link_events(names) == ["LinkStale", "LinkRestored"]
    assert "GoalReached" in names


async def test_a_second_robot_on_the_same_port_does_not_cancel_the_goal() -> None:
    async with bench() as (setup, robot):
        goal = asyncio.create_task(robot.goto(FAR, timeout=WAIT))
        await far_goal_working(robot)
        # A second connect() to the same robot: the two links take the stream in turn.
        async with galileo.connect(setup.url, map_targets=len(TARGETS)) as other:
            assert other.status is not None
            await setup.clock.advance(3 * STALE)
            assert not goal.done()
        result = await asyncio.wait_for(goal, WAIT)
        assert result.target_id == FAR
        assert robot.link_state is LinkState.UP
    assert Cancel() not in setup.commands
    assert setup.commands == [Goto(FAR)]


async def test_a_new_goal_while_the_stream_is_elsewhere_is_refused_unsent() -> None:
    async with bench() as (setup, robot):
        goal = asyncio.create_task(robot.goto(FAR, timeout=WAIT))
        await far_goal_working(robot)
        setup.sim.muted = True
        await robot.wait_link(LinkState.STALE, timeout=WAIT)
        with pytest.raises(galileo.LinkStale, match="nothing was sent"):
            await robot.goto(NEAR, timeout=WAIT)
        setup.sim.muted = False
        assert (await asyncio.wait_for(goal, WAIT)).target_id == FAR
    assert setup.commands == [Goto(FAR)]
