"""drive(): the speed kept alive at its rate, one stop on every exit, NotReady both ways.

The Simulator over TCP loopback plays the robot; ``record_commands`` logs what reached it,
in wire order.
"""

from __future__ import annotations

import asyncio
import contextlib
import math
from collections.abc import AsyncIterator
from typing import Any

import pytest
from cancel_ways import WAYS, stop_waiting
from sim_integration import WAIT, record_commands

import galileo_async as galileo
from galileo_async import CommandSuperseded, InvalidArgument, NotReady, TargetStatus
from galileo_async.protocol import (
    Backward,
    Command,
    Forward,
    Stop,
    TurnLeft,
    TurnRight,
    Velocity,
    speed_commands,
)
from galileo_async.sim import Simulator

#: Simulated seconds per real second: slow enough for a 3 s watchdog to sit between ticks.
SPEED = 10.0
TARGETS: tuple[tuple[float, float], ...] = ((1.0, 0.0), (40.0, 0.0))
FAR = 1
DRIVE = (Forward, Backward, TurnLeft, TurnRight, Stop)
Log = list[tuple[Command, bool]]


@contextlib.asynccontextmanager
async def robot_and_log(
    *, navigate: bool = False, **sim_options: Any
) -> AsyncIterator[tuple[galileo.Robot, Log]]:
    """A Robot on a Simulator over TCP, and the log of commands the simulator received."""
    options: dict[str, Any] = {"speed": SPEED, "targets": TARGETS, **sim_options}
    async with Simulator(**options) as sim:
        server = await sim.serve_tcp()
        url = f"socket://127.0.0.1:{server.sockets[0].getsockname()[1]}"
        async with galileo.connect(url, map_targets=len(TARGETS)) as robot:
            if navigate:
                await robot.start_navigation(timeout=WAIT)
            yield robot, record_commands(sim)


def drive_commands(log: Log) -> list[Command]:
    return [command for command, _busy in log if isinstance(command, DRIVE)]


async def stopped(robot: galileo.Robot) -> None:
    await robot.wait_until(
        lambda s: s.control_speed_x == 0.0 and s.control_speed_theta == 0.0, timeout=WAIT
    )


def assert_one_stop_last(log: Log) -> None:
    wire = drive_commands(log)
    assert wire[-1] == Stop(), wire
    assert wire.count(Stop()) == 1, wire
    assert Forward(50) in wire, wire  # the session did drive first
    assert TurnLeft(40) in wire, wire


async def drive_forever(robot: galileo.Robot) -> None:
    async with robot.drive(0.4, 0.6, rate=20):
        await asyncio.sleep(60)


# --- the keep-alive ------------------------------------------------------------------


async def test_the_speed_is_re_sent_at_the_rate_then_one_stop() -> None:
    async with robot_and_log() as (robot, log):
        async with robot.drive(0.4, -0.6, rate=20) as d:
            await asyncio.sleep(0.5)
            assert d.active
        assert not d.active
        await stopped(robot)
    wire = drive_commands(log)
    # 0.5 s at 20 Hz: the first write and about 10 ticks, each both components.
    ticks = wire.count(Forward(50))
    assert 6 <= ticks <= 14, wire
    assert wire.count(TurnRight(40)) == ticks
    assert wire[:2] == [Forward(50), TurnRight(40)]  # linear first: c/d reads it
    assert wire[-1] == Stop()
    assert wire.count(Stop()) == 1


async def test_the_keep_alive_beats_the_chassis_watchdog() -> None:
    # A chassis that stops 3 s after the last speed command (chitu-noetic, VENDOR.md §2.5).
    async with robot_and_log(cmd_vel_timeout=3.0) as (robot, _log):
        await robot.forward(50)
        await robot.wait_until(lambda s: s.control_speed_x == 0.0, timeout=WAIT)  # one-shot
        async with robot.drive(0.4, rate=5):
            await asyncio.sleep(6.0 / SPEED)  # twice the watchdog's 3 s
            status = robot.status
            assert status is not None
            assert status.control_speed_x == pytest.approx(0.4, abs=1e-3)


async def test_set_writes_at_once_not_at_the_next_tick() -> None:
    # At 2 Hz the first tick comes 0.5 s after the write that opened the block; set() is
    # called at once, so a Forward(25) seen well before that was written by set() itself.
    loop = asyncio.get_running_loop()
    async with robot_and_log() as (robot, log), robot.drive(0.4, rate=2) as d:
        opened = loop.time()
        d.set(linear=0.2)
        assert (d.linear, d.angular) == (0.2, 0.0)
        await robot.wait_until(
            lambda s: s.control_speed_x == pytest.approx(0.2, abs=1e-3), timeout=WAIT
        )
        confirmed = loop.time() - opened
        forwards = [c for c in drive_commands(log) if isinstance(c, Forward)]
    assert forwards[-1] == Forward(25), forwards
    assert Forward(50) not in forwards[1:], forwards  # no tick of the old speed came between
    assert confirmed < 0.5, f"set()'s speed took {confirmed:.2f} s: written at the next tick?"


async def test_linear_and_angular_make_an_arc() -> None:
    async with robot_and_log(navigate=True) as (robot, _log):
        async with robot.drive(0.4, 0.8, rate=10):
            await robot.wait_until(lambda s: (s.current_angle or 0.0) > 1.0, timeout=WAIT)
            status = robot.status
        assert status is not None
        assert status.control_speed_x == pytest.approx(0.4, abs=1e-3)
        assert status.control_speed_theta == pytest.approx(0.8, abs=0.01)
        assert status.current_pose_x is not None
        assert status.current_pose_y is not None
        assert status.current_pose_x > 0.1
        assert status.current_pose_y > 0.1


# --- every way out writes one stop, last ------------------------------------------------


@pytest.mark.parametrize("how", WAYS)
async def test_every_cancellation_route_writes_one_stop_last(how: str) -> None:
    async with robot_and_log() as (robot, log):
        await stop_waiting(how, lambda: drive_forever(robot), after=0.2)
        await stopped(robot)
        await asyncio.sleep(0.2)  # four periods: nothing more may come
    assert_one_stop_last(log)


async def test_an_exception_inside_writes_one_stop_and_propagates() -> None:
    async def failing() -> None:
        async with robot.drive(0.4, 0.6, rate=20):
            await asyncio.sleep(0.1)
            raise RuntimeError("inside")

    async with robot_and_log() as (robot, log):
        with pytest.raises(RuntimeError, match="inside"):
            await failing()
        await stopped(robot)
        await asyncio.sleep(0.2)
    assert_one_stop_last(log)


async def test_close_inside_writes_the_stop_before_closing() -> None:
    async with robot_and_log() as (robot, log), robot.drive(0.4, 0.6, rate=20) as d:
        await asyncio.sleep(0.1)
        await robot.close()
        assert not d.active
        with pytest.raises(CommandSuperseded):
            d.set(linear=0.1)
    assert_one_stop_last(log)


async def test_a_user_stop_inside_ends_the_session() -> None:
    async with robot_and_log() as (robot, log):
        async with robot.drive(0.4, 0.6, rate=20) as d:
            await asyncio.sleep(0.1)
            await robot.stop()
            await asyncio.sleep(0.2)
            assert not d.active
            with pytest.raises(CommandSuperseded):
                d.set(linear=0.1)
        await asyncio.sleep(0.1)
    wire = drive_commands(log)
    first_stop = wire.index(Stop())
    assert set(wire[first_stop:]) == {Stop()}, wire  # the user's stop, then the exit's


@pytest.mark.parametrize("user_stop", ["cancel", "pause", "stop_navigation"])
async def test_any_user_stop_inside_stops_the_wheels_at_once(user_stop: str) -> None:
    async with robot_and_log(navigate=True) as (robot, log):
        async with robot.drive(0.4, 0.6, rate=20) as d:
            await asyncio.sleep(0.1)
            with contextlib.suppress(galileo.NotReady):  # pause() with no goal working
                await getattr(robot, user_stop)()
            assert not d.active
            await stopped(robot)  # the session's stop came with the user's stop, not at exit
            with pytest.raises(CommandSuperseded):
                d.set(linear=0.1)
        await asyncio.sleep(0.1)
    wire = drive_commands(log)
    assert wire.count(Stop()) == 1, wire  # written once, at the user's stop
    assert wire[-1] == Stop(), wire


# --- validation, NotReady -----------------------------------------------------------


@pytest.mark.parametrize(
    ("args", "kwargs"),
    [
        ((0.81, 0.0), {}),
        ((-0.81, 0.0), {}),
        ((0.0, 1.51), {}),
        ((math.nan, 0.0), {}),
        ((0.0, math.inf), {}),
        (("0.1", 0.0), {}),
        ((0.1, 0.0), {"rate": 1.9}),
        ((0.1, 0.0), {"rate": 20.5}),
        ((0.1, 0.0), {"rate": math.nan}),
    ],
)
async def test_bad_values_are_invalid_before_anything_is_sent(
    args: tuple[Any, ...], kwargs: dict[str, Any]
) -> None:
    async with robot_and_log() as (robot, log):
        with pytest.raises(InvalidArgument):
            robot.drive(*args, **kwargs)
        async with robot.drive(0.1, rate=20) as d:
            for bad in ({"linear": 0.9}, {"angular": -2.0}, {"linear": math.inf}):
                with pytest.raises(InvalidArgument):
                    d.set(**bad)
            assert (d.linear, d.angular) == (0.1, 0.0)
    assert all(command in (Forward(12), TurnLeft(0), Stop()) for command in drive_commands(log))


async def test_the_limits_are_connect_options() -> None:
    for bad in (0, -1.0, math.nan, "fast", 11.0):
        with pytest.raises(InvalidArgument, match="max_linear_speed"):
            galileo.connect("sim://", max_linear_speed=bad)
        with pytest.raises(InvalidArgument, match="max_angular_speed"):
            galileo.connect("sim://", max_angular_speed=bad)
    # A robot whose node runs max_vel 0.4 and max_theta 1.2 (a noetic build).
    async with Simulator(speed=SPEED, max_speed=0.4, max_turn_rate=1.2) as sim:
        server = await sim.serve_tcp()
        url = f"socket://127.0.0.1:{server.sockets[0].getsockname()[1]}"
        async with galileo.connect(url, max_linear_speed=0.4, max_angular_speed=1.2) as robot:
            log = record_commands(sim)
            with pytest.raises(InvalidArgument):
                robot.drive(0.5)
            async with robot.drive(0.4, 1.2):
                await robot.wait_until(
                    lambda s: (
                        s.control_speed_x == pytest.approx(0.4, abs=1e-3)
                        and s.control_speed_theta == pytest.approx(1.2, abs=1e-3)
                    ),
                    timeout=WAIT,
                )
    assert drive_commands(log)[:2] == [Forward(100), TurnLeft(100)]


async def test_a_speed_the_percentages_cannot_carry_is_invalid() -> None:
    # The vendor divides the angular by |linear| from 1 m/s: 1.2 rad/s at 1.5 m/s needs 120 %.
    async with Simulator(speed=SPEED, max_speed=2.0) as sim:
        server = await sim.serve_tcp()
        url = f"socket://127.0.0.1:{server.sockets[0].getsockname()[1]}"
        async with galileo.connect(url, max_linear_speed=2.0) as robot:
            log = record_commands(sim)
            with pytest.raises(InvalidArgument, match="exceed"):
                robot.drive(1.5, 1.2)
            async with robot.drive(1.5, 0.6) as d:
                with pytest.raises(InvalidArgument, match="exceed"):
                    d.set(angular=1.2)
                assert (d.linear, d.angular) == (1.5, 0.6)
    assert drive_commands(log)[-1] == Stop()


async def test_over_a_pty_too() -> None:
    async with Simulator(speed=SPEED) as sim, galileo.connect(sim.open_pty()) as robot:
        log = record_commands(sim)
        await stop_waiting("cancel", lambda: drive_forever(robot), after=0.2)
        await stopped(robot)
        await asyncio.sleep(0.2)
    assert_one_stop_last(log)


async def test_a_goal_inside_a_drive_is_not_ready() -> None:
    async with robot_and_log(navigate=True) as (robot, log):
        async with robot.drive(0.2, rate=20):
            for call in (
                lambda: robot.goto(FAR, timeout=WAIT),
                lambda: robot.goto_point(2.0, 0.0, timeout=WAIT),
                lambda: robot.start_patrol(timeout=WAIT),
            ):
                with pytest.raises(NotReady, match="drive session is active"):
                    await call()
            with pytest.raises(NotReady, match="another drive session"):
                async with robot.drive(0.1):
                    pass
        await robot.goto(0, timeout=WAIT)  # allowed again once the block is left
    kinds = {type(command).__name__ for command, _busy in log}
    assert "ResetTargets" not in kinds
    assert "StartPatrol" not in kinds


async def test_drive_while_a_goal_runs_is_not_ready() -> None:
    async with robot_and_log(navigate=True) as (robot, log):
        goal = asyncio.create_task(robot.goto(FAR, timeout=WAIT))
        await robot.wait_until(lambda s: s.target_status == TargetStatus.WORKING, timeout=WAIT)
        with pytest.raises(NotReady, match="goal 1 is active"):
            async with robot.drive(0.2):
                pass
        await robot.pause()
        with pytest.raises(NotReady, match="goal 1 is active"):
            async with robot.drive(0.2):
                pass
        goal.cancel()
        with pytest.raises(asyncio.CancelledError):
            await goal
    assert drive_commands(log) == []


async def test_a_velocity_command_is_refused_on_a_serial_link() -> None:
    async with robot_and_log() as (robot, log):
        with pytest.raises(InvalidArgument, match="ros://"):
            await robot.send(Velocity(0.1, 0.0))
    assert log == []


# --- the serial encoding -------------------------------------------------------------


def test_speed_commands_keep_both_components() -> None:
    limits = {"max_linear": 0.8, "max_angular": 1.5}
    assert speed_commands(0.0, 0.0, **limits) == (Forward(0), TurnLeft(0))
    assert speed_commands(-0.4, 0.75, **limits) == (Backward(50), TurnLeft(50))
    assert speed_commands(0.8, -1.5, **limits) == (Forward(100), TurnRight(100))
    # The vendor divides the angular by |linear.x| once it is 1 m/s or more: compensate.
    assert speed_commands(1.5, 0.6, max_linear=2.0, max_angular=1.2) == (
        Forward(75),
        TurnLeft(75),
    )
    with pytest.raises(InvalidArgument):
        speed_commands(2.0, 1.0, max_linear=2.0, max_angular=1.2)
