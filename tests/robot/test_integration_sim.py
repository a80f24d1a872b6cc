"""Navigation, teleop, rotate, the host, layouts and faults end to end against the Simulator.

A real Robot (``galileo_async.connect``) on ``socket://127.0.0.1:PORT`` (``serve_tcp``) or
on a pty path (``open_pty``) against a real ``Simulator`` running 80x faster than real time.
Goals are in test_integration_goals.py; patrol, mapping and charging in
test_integration_services.py; the harness in sim_integration.py.

The matrix (``sim_integration.MODES``): firmware {real, document} × layout {v2,
v2_truncated, v1, v1_charge} gives 8 cells; each cell is served over one transport, chosen
so that every layout and every firmware mode meets both TCP and the pty (a Latin square:
8 connections per operation instead of the 16 of a full cross). Every operation runs in
all 8 cells; where a layout cannot show the effect, the test asserts the documented
behaviour (``UnconfirmedOperation`` at once, fields None) and checks the effect on the
simulator's own state instead of skipping. Only behaviours that exist in one firmware
mode are split by mode (invalid goal ids, rotate); the disconnect fault spares the pty by
design, which its cells assert. The whole set runs in about 25 s on 2 cores.
"""

from __future__ import annotations

import asyncio
import math
from collections.abc import Awaitable, Callable
from functools import partial

import pytest

import galileo_async as galileo
from galileo_async import (
    AngleGoalStatus,
    ConnectionLost,
    InvalidArgument,
    LinkStale,
    NotReady,
    TargetStatus,
    UnconfirmedOperation,
    VisualStatus,
)
from galileo_async.events import ConnectionLostEvent, Event, LinkStaleEvent
from galileo_async.models import STATUS_FIELDS, GalileoStatus
from galileo_async.sim import SimState
from tests.support.sim_integration import (
    NEAR,
    WAIT,
    Mode,
    modes,
    near,
    robot_on_sim,
    sim_reaches,
    sim_seconds,
)

SHORT = sim_seconds(8)


def _speeds(speed: float, turn_rate: float) -> Callable[[GalileoStatus], bool]:
    """The commanded speeds are ``speed`` m/s and ``turn_rate`` rad/s."""

    def check(status: GalileoStatus) -> bool:
        return near(status.control_speed_x, speed) and near(status.control_speed_theta, turn_rate)

    return check


def _sim_status_is(predicate: Callable[[GalileoStatus], bool], state: SimState) -> bool:
    return predicate(state.status)


@modes()
async def test_navigation_start_and_stop(mode: Mode) -> None:
    # Real firmware ignores a start within 5-30 s of the previous one; the document does not.
    ignore = 100.0 if mode.real else None
    async with robot_on_sim(mode, navigate=False, start_ignore_time=ignore) as (sim, robot):
        status = robot.status
        assert status is not None
        assert not status.navigating
        # The firmware's defaults before any goal (docs/protocol.md §1).
        assert (status.target_num_id, status.target_status) == (-1, TargetStatus.INVALID)
        assert status.target_distance == -1.0

        await robot.start_navigation(timeout=WAIT)
        assert robot.status is not None
        assert robot.status.visual_initialised
        assert sim.state.status.nav_status == 1
        sent = robot.link.commands_sent
        await robot.start_navigation(timeout=WAIT)  # already open: nothing sent
        assert robot.link.commands_sent == sent

        await robot.stop_navigation(timeout=WAIT)
        assert robot.status is not None
        assert not robot.status.navigating
        assert robot.status.visual_status == VisualStatus.OFF
        assert sim.state.status.nav_status == 0
        with pytest.raises(NotReady, match="navigation must be open"):
            await robot.goto(NEAR)

        if mode.real:
            # docs/protocol.md §2.a.
            with pytest.raises(UnconfirmedOperation, match="ignores a start"):
                await robot.start_navigation(timeout=SHORT)
            assert sim.state.status.nav_status == 0
        else:
            await robot.start_navigation(timeout=WAIT)
            assert sim.state.status.nav_status == 1


@modes()
async def test_teleop_speeds_persist_until_stop(mode: Mode) -> None:
    async with robot_on_sim(mode, navigate=False) as (sim, robot):
        goal_before = sim.state.status.target_status
        steps: list[tuple[Callable[[], Awaitable[None]], float, float]] = [
            (lambda: robot.forward(50), 0.4, 0.0),
            (lambda: robot.turn_left(50), 0.4, 0.75),  # f then c: an arc
            (lambda: robot.stop(), 0.0, 0.0),
            (lambda: robot.backward(25), -0.2, 0.0),
            (lambda: robot.turn_right(100), -0.2, -1.5),
            (lambda: robot.stop(brake=50), 0.0, 0.0),
        ]
        for operation, speed, turn_rate in steps:
            await operation()
            commanded = _speeds(speed, turn_rate)
            status = await sim_reaches(robot, sim, partial(_sim_status_is, commanded))
            if mode.has("control_speed_x"):
                await robot.wait_until(commanded, timeout=WAIT)
            else:
                assert status.control_speed_x is None
                assert status.current_speed_x is None
        # Teleop works without navigation, moved the robot and left the goal alone.
        assert sim.state.pose.x != 0.0
        assert sim.state.status.target_status == goal_before
        sent = robot.link.commands_sent
        with pytest.raises(InvalidArgument):
            await robot.forward(101)
        assert robot.link.commands_sent == sent


@modes(lambda mode: mode.real)
async def test_rotate_is_ignored_by_real_firmware(mode: Mode) -> None:
    async with robot_on_sim(mode) as (sim, robot):
        with pytest.raises(UnconfirmedOperation, match="ignore the rotate command 'a'"):
            await robot.rotate_to(90, timeout=SHORT)
        assert sim.state.pose.theta == 0.0
        # Firmware derives angle_goal_status from the goal state (docs/protocol.md §1, §2.g).
        assert robot.status is not None
        if mode.has("angle_goal_status"):
            assert robot.status.angle_goal_status == AngleGoalStatus.INVALID


@modes(lambda mode: not mode.real)
async def test_rotate_completes_on_document_firmware(mode: Mode) -> None:
    async with robot_on_sim(mode) as (sim, robot):
        await robot.rotate_to(90, timeout=WAIT)
        assert near(sim.state.pose.theta, math.pi / 2)
        assert robot.status is not None
        assert robot.status.angle_goal_status == AngleGoalStatus.DONE
        if mode.has("current_angle"):
            assert near(robot.status.current_angle, math.pi / 2)
        # A second rotation: the 1 (done) left by the first must not end it early.
        await robot.rotate_to(-45, timeout=WAIT)
        assert near(sim.state.pose.theta, -math.pi / 4)
        # To the heading it already has: done at once, yet seen as a new rotation.
        await robot.rotate_to(-45, timeout=WAIT)
        assert near(sim.state.pose.theta, -math.pi / 4)

        goal = asyncio.create_task(robot.goto(NEAR, timeout=WAIT))
        try:
            await robot.wait_until(lambda s: s.target_status == TargetStatus.WORKING, timeout=WAIT)
            with pytest.raises(NotReady, match="no goal active"):
                await robot.rotate_to(0)
            await asyncio.wait_for(goal, WAIT)
        finally:
            goal.cancel()


async def _first_link_event(robot: galileo.Robot) -> Event:
    async for event in robot.events():
        if isinstance(event, (ConnectionLostEvent, LinkStaleEvent)):  # whichever comes first
            return event
    raise AssertionError("the event stream ended without a link event")


@modes()
async def test_shutdown_host_silences_the_robot(mode: Mode) -> None:
    async with robot_on_sim(mode) as (sim, robot):
        with pytest.raises(InvalidArgument):
            await robot.shutdown_host()
        assert sim.accepting

        events = asyncio.create_task(_first_link_event(robot))
        waiter = asyncio.create_task(robot.wait_until(lambda s: False, timeout=WAIT))
        try:
            await asyncio.sleep(0)  # both are registered before the command goes out
            await robot.shutdown_host(confirm=True)
            # The computer is off: its socket or serial node is gone, and every waiter
            # learns at once instead of waiting for a frame that will never come. UDP has
            # no connection to lose: the silence makes the link stale.
            udp = mode.transport == "udp"
            with pytest.raises(LinkStale if udp else ConnectionLost):
                await asyncio.wait_for(waiter, WAIT)
            event = await asyncio.wait_for(events, WAIT)
        finally:
            events.cancel()
            waiter.cancel()
        assert isinstance(event, LinkStaleEvent if udp else ConnectionLostEvent)
        assert sim.state.shutdown
        assert not sim.accepting
        assert robot.link.stale if udp else not robot.link.connected
        assert robot.status is not None  # the last status is kept
        frames = sim.state.time_stamp
        with pytest.raises(LinkStale if udp else ConnectionLost):  # reconnecting meanwhile
            await robot.goto(NEAR, timeout=WAIT)
        with pytest.raises(LinkStale if udp else ConnectionLost):
            await robot.wait_until(lambda s: True, timeout=WAIT)
        assert sim.state.time_stamp == frames  # the frame clock stopped


@modes()
async def test_layout_fields_are_none_where_missing(mode: Mode) -> None:
    async with robot_on_sim(mode) as (sim, robot):
        await robot.goto(NEAR, timeout=WAIT)
        status = robot.status
        assert status is not None
        assert status.layout is mode.layout
        for field in STATUS_FIELDS:
            assert (getattr(status, field) is None) is (not mode.has(field)), field
        truth = sim.state.status
        for field in ("nav_status", "visual_status", "target_num_id", "target_status"):
            assert getattr(status, field) == getattr(truth, field)
        assert near(status.power, truth.power or 0.0, 0.011)
        if mode.has("current_pose_x"):
            assert status.pose is not None
            assert near(status.pose.x, sim.state.pose.x)
        else:
            assert status.pose is None
        # None-safe views on what the layout lacks: never a crash, never a made-up zero.
        assert not status.mapping
        assert not status.patrolling
        assert not status.is_busy
        if not mode.has("charge_status"):
            assert not status.charging
        if mode.has("time_stamp"):
            assert status.time_stamp is not None
            assert 0 < status.time_stamp <= sim.state.time_stamp


@modes()
async def test_statuses_and_events_follow_a_goal(mode: Mode) -> None:
    async with robot_on_sim(mode) as (_sim, robot):
        seen: list[GalileoStatus] = []
        names: list[str] = []

        async def watch_events() -> None:
            async for event in robot.events():
                names.append(event.name)
                if names[-1] == "GoalReached":
                    return

        events = asyncio.create_task(watch_events())
        try:
            await asyncio.sleep(0)
            await robot.goto(NEAR, timeout=WAIT)
            await asyncio.wait_for(events, WAIT)
        finally:
            events.cancel()
        assert names.index("GoalAccepted") < names.index("GoalReached")
        async for status in robot.statuses():
            seen.append(status)
            break
        assert seen[0] == robot.status


@modes()
async def test_faults_on_the_wire_are_counted_not_raised(mode: Mode) -> None:
    async with robot_on_sim(mode, garbage=0.2, drop=0.2, seed=3) as (sim, robot):
        result = await robot.goto(NEAR, timeout=WAIT)
        assert result.distance == 0.0
        stats = sim.state.stats
        assert stats.garbage_bytes > 0
        assert stats.frames_dropped > 0
        link = robot.link
        assert link.bytes_discarded > 0
        if mode.has("time_stamp"):
            assert link.lost_frames > 0  # counted from time_stamp gaps


@modes()
async def test_disconnect_fault_and_reconnect(mode: Mode) -> None:
    async with robot_on_sim(mode, disconnect_after=10.0) as (sim, robot):
        if mode.transport in ("pty", "udp"):
            # Closing a pty would remove the device path: the fault spares it (docs/simulator.md);
            # a UDP port has no connection to close.
            await sim_reaches(robot, sim, lambda s: s.time > 25.0)
            assert robot.link.connected
            assert robot.link.reconnects == 0
            return
        names: list[str] = []

        async def until_restored() -> None:
            async for event in robot.events():
                names.append(event.name)
                if names[-1] == "ConnectionRestored":
                    return

        events = asyncio.create_task(until_restored())
        try:
            await asyncio.sleep(0)
            with pytest.raises(ConnectionLost):  # fails at once when the stream drops
                await robot.wait_until(lambda s: False, timeout=WAIT)
            await asyncio.wait_for(events, WAIT)
        finally:
            events.cancel()
        assert names[-2:] == ["ConnectionLost", "ConnectionRestored"]
        assert robot.link.reconnects == 1
        # The same robot, as it was left: navigation still open.
        result = await robot.goto(NEAR, timeout=WAIT)
        assert result.target_id == NEAR
