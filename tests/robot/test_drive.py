"""drive(): the speed kept alive at its rate, one stop on every exit, NotReady both ways.

A simulated_robot() on the virtual clock plays the robot (one test drives it over a
pty, the serial path, on the real clock); ``Wire`` logs what reached it, in order, with
the loop time of its arrival, so rates and "at once" are checked exactly.
"""

from __future__ import annotations

import asyncio
import contextlib
import math
from collections.abc import AsyncIterator
from typing import Any

import pytest

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
from galileo_async.sim import FRAME_RATE, Simulator
from galileo_async.testing import simulated_robot
from tests.support.cancel_ways import WAYS, stop_waiting
from tests.support.sim_integration import WAIT, record_commands

#: The pty test's simulated seconds per real second.
SPEED = 10.0
TARGETS: tuple[tuple[float, float], ...] = ((1.0, 0.0), (40.0, 0.0))
FAR = 1
DRIVE = (Forward, Backward, TurnLeft, TurnRight, Stop)
Log = list[tuple[Command, bool]]
#: Float slack on sums of loop times (the virtual clock lands exactly on each timer).
EXACT = 1e-6
#: The link's pacing: at least this long between two commands (connect's min_command_interval).
PACING = 0.01


class Wire:
    """Every command the simulated robot received, with the loop time it arrived."""

    def __init__(self, sim: Simulator) -> None:
        self.arrivals: list[tuple[float, Command]] = []
        loop = asyncio.get_running_loop()
        model = sim.model
        submit = model.submit

        def recording(command: Command) -> None:
            self.arrivals.append((loop.time(), command))
            submit(command)

        model.submit = recording  # type: ignore[method-assign]

    def commands(self) -> list[Command]:
        """Every command received, in order."""
        return [command for _at, command in self.arrivals]

    def drive(self) -> list[Command]:
        """The drive commands received (speeds and stops), in order."""
        return [command for command in self.commands() if isinstance(command, DRIVE)]

    def times(self, command: Command) -> list[float]:
        """The loop times at which ``command`` arrived."""
        return [at for at, seen in self.arrivals if seen == command]


@contextlib.asynccontextmanager
async def robot_and_wire(
    *, navigate: bool = False, sim_options: dict[str, Any] | None = None, **options: Any
) -> AsyncIterator[tuple[galileo.Robot, Wire]]:
    """A Robot on a simulated robot (virtual clock) and the log of what reached the robot."""
    async with simulated_robot(
        targets=TARGETS,
        navigating=False,
        sim_options=sim_options,
        min_command_interval=PACING,
        **options,
    ) as (robot, device):
        if navigate:
            await robot.start_navigation(timeout=WAIT)
        yield robot, Wire(device.simulator)


async def stopped(robot: galileo.Robot) -> None:
    await robot.wait_until(
        lambda s: s.control_speed_x == 0.0 and s.control_speed_theta == 0.0, timeout=WAIT
    )


def drive_commands(log: Log) -> list[Command]:
    return [command for command, _busy in log if isinstance(command, DRIVE)]


def assert_one_stop_last(wire: list[Command]) -> None:
    assert wire[-1] == Stop(), wire
    assert wire.count(Stop()) == 1, wire
    assert Forward(50) in wire, wire  # the session did drive first
    assert TurnLeft(40) in wire, wire


def assert_stopped_at_once(wire: Wire, left: float) -> None:
    """The first stop reached the robot within one pacing interval of ``left``."""
    stop_at = wire.times(Stop())[0]
    assert left - EXACT <= stop_at <= left + PACING + EXACT, stop_at - left


async def drive_forever(robot: galileo.Robot) -> None:
    async with robot.drive(0.4, 0.6, rate=20):
        await asyncio.sleep(60)


# --- the keep-alive ------------------------------------------------------------------


async def test_the_speed_is_re_sent_at_the_rate_then_one_stop() -> None:
    loop = asyncio.get_running_loop()
    async with robot_and_wire() as (robot, wire):
        async with robot.drive(0.4, -0.6, rate=20) as d:
            opened = loop.time()
            await asyncio.sleep(0.475)  # the first write and 9 ticks, one every 0.05 s
            assert d.active
        left = loop.time()
        assert not d.active
        await stopped(robot)
    drive = wire.drive()
    forwards = wire.times(Forward(50))
    assert forwards == pytest.approx([opened + tick / 20 for tick in range(10)], abs=EXACT)
    # Each write carries both components, the angular one pacing interval after.
    turns = wire.times(TurnRight(40))
    assert turns == pytest.approx([at + PACING for at in forwards], abs=EXACT)
    assert drive[:2] == [Forward(50), TurnRight(40)]  # linear first: c/d reads it
    assert drive[-1] == Stop()
    assert drive.count(Stop()) == 1
    assert_stopped_at_once(wire, left)


async def test_the_keep_alive_beats_the_chassis_watchdog() -> None:
    # A chassis that stops 3 s after the last speed command (chitu-noetic, docs/protocol.md §6.5).
    async with robot_and_wire(sim_options={"cmd_vel_timeout": 3.0}) as (robot, _wire):
        await robot.forward(50)
        await robot.wait_until(lambda s: s.control_speed_x == 0.0, timeout=WAIT)  # one-shot
        async with robot.drive(0.4, rate=5):
            await asyncio.sleep(6.0)  # twice the watchdog's 3 s
            status = robot.status
            assert status is not None
            assert status.control_speed_x == pytest.approx(0.4, abs=1e-3)


async def test_set_writes_at_once_not_at_the_next_tick() -> None:
    # At 2 Hz the first tick comes 0.5 s after the write that opened the block; set() is
    # called at once, so its Forward(25) must reach the robot within one pacing interval
    # and show in the next frame.
    loop = asyncio.get_running_loop()
    async with robot_and_wire() as (robot, wire), robot.drive(0.4, rate=2) as d:
        opened = loop.time()
        d.set(linear=0.2)
        assert (d.linear, d.angular) == (0.2, 0.0)
        await robot.wait_until(
            lambda s: s.control_speed_x == pytest.approx(0.2, abs=1e-3), timeout=WAIT
        )
        confirmed = loop.time() - opened
        forwards = [c for c in wire.drive() if isinstance(c, Forward)]
    assert forwards[-1] == Forward(25), forwards
    assert Forward(50) not in forwards[1:], forwards  # no tick of the old speed came between
    (written,) = wire.times(Forward(25))
    written -= opened
    assert 0.0 <= written <= PACING + EXACT, f"set()'s speed reached the robot after {written} s"
    assert confirmed <= written + 1.0 / FRAME_RATE + EXACT, f"shown only after {confirmed} s"


async def test_linear_and_angular_make_an_arc() -> None:
    async with robot_and_wire(navigate=True) as (robot, _wire):
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
    loop = asyncio.get_running_loop()
    async with robot_and_wire() as (robot, wire):
        started = loop.time()
        await stop_waiting(how, lambda: drive_forever(robot), after=0.2)
        await stopped(robot)
        await asyncio.sleep(0.2)  # four periods: nothing more may come
    assert_one_stop_last(wire.drive())
    assert_stopped_at_once(wire, started + 0.2)


async def test_an_exception_inside_writes_one_stop_and_propagates() -> None:
    loop = asyncio.get_running_loop()

    async def failing() -> None:
        async with robot.drive(0.4, 0.6, rate=20):
            await asyncio.sleep(0.1)
            raised.append(loop.time())
            raise RuntimeError("inside")

    raised: list[float] = []
    async with robot_and_wire() as (robot, wire):
        with pytest.raises(RuntimeError, match="inside"):
            await failing()
        await stopped(robot)
        await asyncio.sleep(0.2)
    assert_one_stop_last(wire.drive())
    assert_stopped_at_once(wire, raised[0])


async def test_close_inside_writes_the_stop_before_closing() -> None:
    loop = asyncio.get_running_loop()
    async with robot_and_wire() as (robot, wire), robot.drive(0.4, 0.6, rate=20) as d:
        await asyncio.sleep(0.1)
        closing = loop.time()
        await robot.close()
        assert not d.active
        with pytest.raises(CommandSuperseded):
            d.set(linear=0.1)
    assert_one_stop_last(wire.drive())
    assert_stopped_at_once(wire, closing)


async def test_a_user_stop_inside_ends_the_session() -> None:
    loop = asyncio.get_running_loop()
    async with robot_and_wire() as (robot, wire):
        async with robot.drive(0.4, 0.6, rate=20) as d:
            await asyncio.sleep(0.1)
            stopping = loop.time()
            await robot.stop()
            await asyncio.sleep(0.2)
            assert not d.active
            with pytest.raises(CommandSuperseded):
                d.set(linear=0.1)
        await asyncio.sleep(0.1)
    drive = wire.drive()
    first_stop = drive.index(Stop())
    assert set(drive[first_stop:]) == {Stop()}, drive  # the user's stop, then the exit's
    assert_stopped_at_once(wire, stopping)


@pytest.mark.parametrize("user_stop", ["cancel", "pause", "stop_navigation"])
async def test_any_user_stop_inside_stops_the_wheels_at_once(user_stop: str) -> None:
    loop = asyncio.get_running_loop()
    async with robot_and_wire(navigate=True) as (robot, wire):
        async with robot.drive(0.4, 0.6, rate=20) as d:
            await asyncio.sleep(0.1)
            stopping = loop.time()
            with contextlib.suppress(galileo.NotReady):  # pause() with no goal working
                await getattr(robot, user_stop)()
            assert not d.active
            await stopped(robot)  # the session's stop came with the user's stop, not at exit
            with pytest.raises(CommandSuperseded):
                d.set(linear=0.1)
        await asyncio.sleep(0.1)
    drive = wire.drive()
    assert drive.count(Stop()) == 1, drive  # written once, at the user's stop
    assert drive[-1] == Stop(), drive
    assert_stopped_at_once(wire, stopping)


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
    async with robot_and_wire() as (robot, wire):
        with pytest.raises(InvalidArgument):
            robot.drive(*args, **kwargs)
        async with robot.drive(0.1, rate=20) as d:
            for bad in ({"linear": 0.9}, {"angular": -2.0}, {"linear": math.inf}):
                with pytest.raises(InvalidArgument):
                    d.set(**bad)
            assert (d.linear, d.angular) == (0.1, 0.0)
    assert all(command in (Forward(12), TurnLeft(0), Stop()) for command in wire.drive())


async def test_the_limits_are_connect_options() -> None:
    for bad in (0, -1.0, math.nan, "fast", 11.0):
        with pytest.raises(InvalidArgument, match="max_linear_speed"):
            galileo.connect("sim://", max_linear_speed=bad)
        with pytest.raises(InvalidArgument, match="max_angular_speed"):
            galileo.connect("sim://", max_angular_speed=bad)
    # A robot whose node runs max_vel 0.4 and max_theta 1.2 (a noetic build).
    async with robot_and_wire(
        sim_options={"max_speed": 0.4, "max_turn_rate": 1.2},
        max_linear_speed=0.4,
        max_angular_speed=1.2,
    ) as (robot, wire):
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
    assert wire.drive()[:2] == [Forward(100), TurnLeft(100)]


async def test_a_speed_the_percentages_cannot_carry_is_invalid() -> None:
    # The vendor divides the angular by |linear| from 1 m/s: 1.2 rad/s at 1.5 m/s needs 120 %.
    async with robot_and_wire(sim_options={"max_speed": 2.0}, max_linear_speed=2.0) as (
        robot,
        wire,
    ):
        with pytest.raises(InvalidArgument, match="exceed"):
            robot.drive(1.5, 1.2)
        async with robot.drive(1.5, 0.6) as d:
            with pytest.raises(InvalidArgument, match="exceed"):
                d.set(angular=1.2)
            assert (d.linear, d.angular) == (1.5, 0.6)
    assert wire.drive()[-1] == Stop()


async def test_over_a_pty_too() -> None:
    async with Simulator(speed=SPEED) as sim, galileo.connect(sim.open_pty()) as robot:
        log = record_commands(sim)
        await stop_waiting("cancel", lambda: drive_forever(robot), after=0.2)
        await stopped(robot)
        await asyncio.sleep(0.2)
    assert_one_stop_last(drive_commands(log))


async def test_a_goal_inside_a_drive_is_not_ready() -> None:
    async with robot_and_wire(navigate=True) as (robot, wire):
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
    kinds = {type(command).__name__ for command in wire.commands()}
    assert "ResetTargets" not in kinds
    assert "StartPatrol" not in kinds


async def test_drive_while_a_goal_runs_is_not_ready() -> None:
    async with robot_and_wire(navigate=True) as (robot, wire):
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
    assert wire.drive() == []


async def test_a_velocity_command_is_refused_on_a_serial_link() -> None:
    async with robot_and_wire() as (robot, wire):
        with pytest.raises(InvalidArgument, match="ros://"):
            await robot.send(Velocity(0.1, 0.0))
    assert wire.arrivals == []


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
