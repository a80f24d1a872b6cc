"""A goal given up on a lost link, or left on a stale one, is cancelled if it runs once back.

The vendor's serial node can die while the navigation computer drives on. Here the
Simulator (the navigation computer) is served over TCP, and a relay in front of it plays
the serial node: it can go away (its connections close), go silent (bytes dropped both
ways), hold bytes back, and come back. The Robot connects to the relay with reconnect on.
"""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import AsyncIterator
from typing import Any, Literal

import anyio
import pytest

import galileo_async as galileo
from galileo_async import ConnectionLost, TargetStatus
from galileo_async import events as ev
from galileo_async.events import AbandonedGoalCancelled
from galileo_async.protocol import Cancel, Command, Goto
from galileo_async.sim import Simulator
from galileo_async.state import EventStream
from tests.support.sim_integration import SPEED, WAIT, record_commands

#: Goal 1 is far enough to still be driving after the outage; goal 0 is near.
TARGETS: tuple[tuple[float, float], ...] = ((1.5, 0.0), (400.0, 0.0))
NEAR, FAR = 0, 1
OPTIONS: dict[str, Any] = {
    "map_targets": len(TARGETS),
    "reconnect": True,
    "reconnect_initial": 0.02,
    "reconnect_max": 0.05,
    "stale_timeout": 0.3,
    "stale_reconnect": None,  # a silent relay keeps its connection: only frames stop
}

ToRobot = Literal["pass", "drop", "hold"]


class Relay:
    """A TCP relay standing for the vendor's serial node between host and robot."""

    def __init__(self, robot_port: int) -> None:
        self.robot_port = robot_port
        self.to_host = True  # False: the robot's frames are dropped
        self.to_robot: ToRobot = "pass"  # "hold": the host's bytes wait for release()
        self.held: list[tuple[asyncio.StreamWriter, bytes]] = []
        self.holding = asyncio.Event()  # set once bytes are held
        self.served = asyncio.Event()  # set when a host connects
        self._writers: list[asyncio.StreamWriter] = []
        self._sessions: set[asyncio.Task[Any]] = set()
        self._server: asyncio.Server | None = None

    @property
    def url(self) -> str:
        assert self._server is not None
        return f"socket://127.0.0.1:{self._server.sockets[0].getsockname()[1]}"

    async def start(self) -> None:
        self._server = await asyncio.start_server(self._serve, "127.0.0.1", 0)

    def go_away(self) -> None:
        """Close every connection (the node died); new ones are served (it restarted)."""
        for writer in self._writers:
            writer.close()

    def release(self) -> None:
        """Forward the held host bytes, and the host's bytes from now on."""
        self.to_robot = "pass"
        held, self.held = self.held, []
        for writer, data in held:
            writer.write(data)

    async def close(self) -> None:
        assert self._server is not None
        self._server.close()
        self.go_away()
        if self._sessions:
            await asyncio.wait(self._sessions, timeout=WAIT)
        await self._server.wait_closed()

    async def _serve(self, host_in: asyncio.StreamReader, host_out: asyncio.StreamWriter) -> None:
        session = asyncio.current_task()
        assert session is not None
        self._sessions.add(session)
        self.served.set()
        robot_in, robot_out = await asyncio.open_connection("127.0.0.1", self.robot_port)
        self._writers += [host_out, robot_out]
        try:
            await asyncio.gather(
                self._to_host(robot_in, host_out), self._to_robot(host_in, robot_out)
            )
        except (ConnectionError, OSError):
            pass
        finally:
            for writer in (host_out, robot_out):
                writer.close()
                self._writers.remove(writer)
            self._sessions.discard(session)

    async def _to_host(self, source: asyncio.StreamReader, sink: asyncio.StreamWriter) -> None:
        while data := await source.read(4096):
            if self.to_host:
                sink.write(data)
        sink.close()

    async def _to_robot(self, source: asyncio.StreamReader, sink: asyncio.StreamWriter) -> None:
        while data := await source.read(4096):
            if self.to_robot == "pass":
                sink.write(data)
            elif self.to_robot == "hold":
                self.held.append((sink, data))
                self.holding.set()
        sink.close()


@contextlib.asynccontextmanager
async def robot_via_relay(
    **options: Any,
) -> AsyncIterator[tuple[galileo.Robot, Relay, Simulator, list[tuple[Command, bool]]]]:
    """A navigating Robot reaching the Simulator through a Relay, and the robot's command log."""
    async with Simulator(speed=SPEED, targets=TARGETS) as sim:
        server = await sim.serve_tcp()
        relay = Relay(server.sockets[0].getsockname()[1])
        await relay.start()
        try:
            async with galileo.connect(relay.url, **(OPTIONS | options)) as robot:
                await robot.start_navigation(timeout=WAIT)
                yield robot, relay, sim, record_commands(sim)
        finally:
            await relay.close()


async def _driving_to_far(robot: galileo.Robot, **options: Any) -> asyncio.Task[Any]:
    task = asyncio.create_task(robot.goto(FAR, **options))
    await robot.wait_until(
        lambda s: s.target_num_id == FAR and s.target_status == TargetStatus.WORKING,
        timeout=WAIT,
    )
    return task


def _sim_goal_active(sim: Simulator) -> bool:
    return sim.state.status.target_status in (TargetStatus.WORKING, TargetStatus.PAUSED)


async def _next_event(events: Any, kind: type[ev.Event]) -> ev.Event:
    with anyio.fail_after(WAIT):
        async for event in events:
            if isinstance(event, kind):
                return event
    raise AssertionError(f"events ended without {kind.__name__}")


async def test_a_goal_lost_with_the_connection_is_cancelled_once_it_is_back() -> None:
    async with robot_via_relay() as (robot, relay, sim, log):
        events = robot.events()
        goal = await _driving_to_far(robot)
        relay.go_away()
        with anyio.fail_after(WAIT), pytest.raises(ConnectionLost):
            await goal
        assert _sim_goal_active(sim)  # the robot drives on, unseen
        event = await _next_event(events, AbandonedGoalCancelled)
        assert isinstance(event, AbandonedGoalCancelled)
        assert event.target_id == FAR
        assert event.status is not None
        assert event.status.target_num_id == FAR
        await robot.wait_until(lambda s: not s.goal_active, timeout=WAIT)
        assert not _sim_goal_active(sim)
        assert robot.link.reconnects == 1
    assert [command for command, _ in log] == [Goto(FAR), Cancel()]


async def test_a_goal_left_on_a_silent_link_is_cancelled_once_frames_are_back() -> None:
    async with robot_via_relay() as (robot, relay, sim, log):
        events = robot.events()
        goal = await _driving_to_far(robot)
        relay.to_host, relay.to_robot = False, "drop"  # the node hangs: its exit cancel is lost
        await _next_event(events, ev.LinkStaleEvent)  # the goal goes on while stale …
        assert not goal.done()
        goal.cancel()  # … until its caller leaves (Ctrl-C): i 2 is sent, and lost
        with anyio.fail_after(WAIT), pytest.raises(asyncio.CancelledError):
            await goal
        assert _sim_goal_active(sim)
        relay.to_host, relay.to_robot = True, "pass"
        event = await _next_event(events, AbandonedGoalCancelled)
        assert isinstance(event, AbandonedGoalCancelled)
        assert event.target_id == FAR
        await robot.wait_until(lambda s: not s.goal_active, timeout=WAIT)
    assert [command for command, _ in log] == [Goto(FAR), Cancel()]


async def test_cancel_on_exit_false_leaves_the_abandoned_goal_running() -> None:
    async with robot_via_relay() as (robot, relay, sim, log):
        events = robot.events()
        goal = await _driving_to_far(robot, cancel_on_exit=False)
        relay.go_away()
        with anyio.fail_after(WAIT), pytest.raises(ConnectionLost):
            await goal
        await _next_event(events, ev.ConnectionRestored)
        # Many frames after the link is back, the goal still runs, and no event told of it.
        await _frames(robot, 30)
        assert _sim_goal_active(sim)
        assert robot.status is not None
        assert robot.status.target_status == TargetStatus.WORKING
    assert [command for command, _ in log] == [Goto(FAR)]
    assert not any(isinstance(e, AbandonedGoalCancelled) for e in await _rest(events))


async def test_a_goal_that_ended_meanwhile_gets_no_cancel() -> None:
    async with robot_via_relay() as (robot, relay, _sim, log):
        events = robot.events()
        goal = await _driving_to_far(robot)
        relay.served.clear()
        relay.go_away()
        relay.to_host = False  # the link stays silent after the reconnect
        with anyio.fail_after(WAIT), pytest.raises(ConnectionLost):
            await goal
        # Meanwhile another host cancels it directly on the robot.
        async with galileo.connect(
            f"socket://127.0.0.1:{relay.robot_port}", map_targets=len(TARGETS)
        ) as other:
            await other.cancel(timeout=WAIT)
        await asyncio.wait_for(relay.served.wait(), WAIT)  # reconnected, and silent
        relay.to_host = True
        await _next_event(events, ev.ConnectionRestored)  # once frames come
        await _frames(robot, 30)
        assert robot.status is not None
        assert not robot.status.goal_active
    assert [command for command, _ in log] == [Goto(FAR), Cancel()]  # the other host's
    assert not any(isinstance(e, AbandonedGoalCancelled) for e in await _rest(events))


async def test_a_goal_asked_for_before_the_first_frame_after_a_drop_is_refused() -> None:
    async with robot_via_relay(stale_timeout=WAIT) as (robot, relay, _sim, log):
        events = robot.events()
        goal = await _driving_to_far(robot)
        relay.to_host = False
        relay.served.clear()
        relay.go_away()
        with anyio.fail_after(WAIT), pytest.raises(ConnectionLost):
            await goal
        await asyncio.wait_for(relay.served.wait(), WAIT)
        # Reopened, but no frame yet: the link is still lost, and a goal is refused unsent.
        with pytest.raises(ConnectionLost, match="nothing was sent"):
            await robot.goto(NEAR, timeout=WAIT)
        relay.to_host = True  # the first frames still show the abandoned goal working
        event = await _next_event(events, AbandonedGoalCancelled)
        assert isinstance(event, AbandonedGoalCancelled)
        assert event.target_id == FAR
    assert [command for command, _ in log] == [Goto(FAR), Cancel()]


async def _frames(robot: galileo.Robot, count: int) -> galileo.GalileoStatus:
    """The status ``count`` frames from now."""
    until = robot.link.frames + count
    return await robot.wait_until(lambda _s: robot.link.frames >= until, timeout=WAIT)


async def _rest(events: Any) -> list[ev.Event]:
    """The events still buffered in an events() iterator (which this closes)."""
    assert isinstance(events, EventStream)
    events.close()
    return [event async for event in events]


async def test_closing_while_an_abandoned_goal_waits_for_the_link_leaves_nothing() -> None:
    async with robot_via_relay() as (robot, relay, sim, log):
        goal = await _driving_to_far(robot)
        relay.to_host = False
        relay.go_away()
        with anyio.fail_after(WAIT), pytest.raises(ConnectionLost):
            await goal
        await robot.close()  # the check for the abandoned goal is dropped with the store
        relay.to_host = True
        assert _sim_goal_active(sim)
    assert [command for command, _ in log] == [Goto(FAR)]
