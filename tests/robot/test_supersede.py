"""A user stop supersedes every drive or goal command that still waits to be written.

A simulated_robot() on the virtual clock plays the robot; ``device.busy()`` makes it report
busy_status 1 on demand, so a drive or goal command waits in the busy back-off. The
simulator's command log is the witness of what reached the wire.
"""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import AsyncIterator, Awaitable, Callable
from typing import Any

import anyio
import pytest

import galileo_async as galileo
from galileo_async import CommandSuperseded, GalileoError, GoalCancelled, StopUnconfirmed
from galileo_async.protocol import (
    AddTarget,
    Backward,
    Cancel,
    Command,
    Forward,
    Goto,
    ResetTargets,
    Stop,
    StopPatrol,
    TurnLeft,
    TurnRight,
)
from galileo_async.testing import SimulatedDevice, simulated_robot
from tests.support.cancel_ways import WAYS, stop_waiting
from tests.support.scripted_robot import DEFAULTS, READY, ScriptedRobot, connected, flush
from tests.support.sim_integration import FAR, MAP_TARGETS, RIGHT, TARGETS, WAIT, record_commands

Call = Callable[[galileo.Robot], Awaitable[Any]]

#: The drive and goal calls a stop supersedes, the error each raises, and its commands.
SUPERSEDED: dict[str, tuple[Call, type[GalileoError]]] = {
    "forward": (lambda r: r.forward(30, timeout=WAIT), CommandSuperseded),
    "backward": (lambda r: r.backward(30, timeout=WAIT), CommandSuperseded),
    "turn_left": (lambda r: r.turn_left(30, timeout=WAIT), CommandSuperseded),
    "turn_right": (lambda r: r.turn_right(30, timeout=WAIT), CommandSuperseded),
    "goto": (lambda r: r.goto(FAR, timeout=WAIT), GoalCancelled),
    "goto_point": (lambda r: r.goto_point(10.0, 0.0, timeout=WAIT), GoalCancelled),
    "send(Goto)": (lambda r: r.send(Goto(FAR), timeout=WAIT), CommandSuperseded),
}
#: Commands that must never reach the robot once superseded.
MOVING = (Forward, Backward, TurnLeft, TurnRight, Goto, AddTarget, ResetTargets)

#: The user stops, each with the name its CommandSuperseded carries.
STOPS: dict[str, Call] = {
    "stop()": lambda r: r.stop(),
    "cancel()": lambda r: r.cancel(timeout=WAIT),
    "pause()": lambda r: r.pause(timeout=WAIT),
    "stop_navigation()": lambda r: r.stop_navigation(timeout=WAIT),
    "close()": lambda r: r.close(),
}
#: Well under any wait the superseded call could have made (the busy hold is WAIT long).
AT_ONCE = 1.0
#: Float slack on loop times (the virtual clock stands still while callbacks run).
EXACT = 1e-9
#: A slow link's pacing: one write every PACING seconds keeps a command queued.
PACING = 0.5


@contextlib.asynccontextmanager
async def busy_robot(
    **options: Any,
) -> AsyncIterator[tuple[SimulatedDevice, galileo.Robot, list[tuple[Command, bool]]]]:
    """A navigating simulated robot, busy (busy_status 1) until released, and its command log."""
    async with simulated_robot(targets=TARGETS, navigating=False, **options) as (robot, device):
        await robot.start_navigation(timeout=WAIT)
        log = record_commands(device.simulator)
        device.busy(WAIT)
        await robot.wait_until(lambda s: s.is_busy, timeout=WAIT)
        yield device, robot, log


async def waiting(robot: galileo.Robot, call: Call) -> asyncio.Task[Any]:
    """``call(robot)`` in a task that has reached its first wait (the busy back-off here)."""
    task = asyncio.ensure_future(call(robot))
    await asyncio.sleep(0)  # up to its first await: nothing before it waits
    assert not task.done()
    return task


async def superseded_at_once(
    task: asyncio.Task[Any], error: type[GalileoError], by: str, *, within: float = 0.0
) -> None:
    """``task`` ends with ``error`` naming the stop ``by``, ``within`` loop seconds (0: at once)."""
    loop = asyncio.get_running_loop()
    began = loop.time()
    with anyio.fail_after(AT_ONCE), pytest.raises(error) as caught:
        await task
    took = loop.time() - began
    assert took <= within + EXACT, f"superseded after {took} s"
    superseded = caught.value if error is CommandSuperseded else caught.value.__cause__
    assert isinstance(superseded, CommandSuperseded)
    assert superseded.superseded_by == by


def moving(log: list[tuple[Command, bool]]) -> list[Command]:
    """The drive and goal commands in ``log``."""
    return [command for command, _busy in log if isinstance(command, MOVING)]


async def written(robot: galileo.Robot, log: list[tuple[Command, bool]], command: Command) -> None:
    """Wait until the simulator has received ``command``."""
    await robot.wait_until(lambda _s: any(c == command for c, _ in log), timeout=WAIT)


@pytest.mark.parametrize("stop", STOPS)
@pytest.mark.parametrize("name", SUPERSEDED)
async def test_a_user_stop_supersedes_a_call_waiting_out_busy(name: str, stop: str) -> None:
    call, error = SUPERSEDED[name]
    async with busy_robot() as (device, robot, log):
        task = await waiting(robot, call)
        stopping = asyncio.ensure_future(STOPS[stop](robot))
        await superseded_at_once(task, error, stop)
        device.busy(0)  # the robot is free again: the stop itself may end
        with contextlib.suppress(GalileoError):  # pause() without a goal is NotReady
            await stopping
        if stop != "close()":
            await robot.forward(10)  # called after the stop: sent as usual
            await written(robot, log, Forward(10))
            await robot.stop()
        assert moving(log) == ([] if stop == "close()" else [Forward(10)])


async def test_a_goal_called_after_cancel_still_runs() -> None:
    async with busy_robot() as (device, robot, log):
        task = await waiting(robot, lambda r: r.goto(FAR, timeout=WAIT))
        await robot.cancel(timeout=WAIT)
        with pytest.raises(GoalCancelled, match="cancelled before it was sent"):
            await task
        device.busy(0)
        later = asyncio.ensure_future(robot.goto(FAR, timeout=WAIT))
        await written(robot, log, Goto(FAR))
        await robot.cancel(timeout=WAIT)
        with pytest.raises(GoalCancelled):
            await later
        assert moving(log) == [Goto(FAR)]


async def test_a_stop_between_the_steps_of_goto_point_stops_the_rest() -> None:
    # One write every 0.5 s: ``g i`` waits in the link's queue once ``g r 0`` is written.
    async with busy_robot(min_command_interval=PACING) as (device, robot, log):
        device.busy(0)
        await robot.wait_until(lambda s: not s.is_busy, timeout=WAIT)
        sent = robot.link.commands_sent
        task = asyncio.ensure_future(robot.goto_point(10.0, 0.0, timeout=WAIT))
        await robot.wait_until(lambda _s: robot.link.commands_sent > sent, timeout=WAIT)
        await robot.stop()
        await superseded_at_once(task, GoalCancelled, "stop()")
        await written(robot, log, Stop(100))
        await robot.forward(10)
        await written(robot, log, Forward(10))
        assert moving(log) == [ResetTargets(), Forward(10)]


async def test_a_drive_command_queued_behind_the_pacing_is_dropped() -> None:
    # One write every 0.5 s: a drive command waits in the link's queue, past every check.
    async with busy_robot(min_command_interval=PACING) as (device, robot, log):
        device.busy(0)
        await robot.wait_until(lambda s: not s.is_busy, timeout=WAIT)
        await robot.zero_speed()  # written now: the next write waits 0.5 s
        task = await waiting(robot, lambda r: r.forward(30, timeout=WAIT))
        stopping = asyncio.ensure_future(robot.stop())
        await superseded_at_once(task, CommandSuperseded, "stop()")
        await stopping
        await robot.forward(10)  # queued after the stop: written after it
        await written(robot, log, Forward(10))
        sent = [command for command, _ in log]
        assert sent == [Stop(100), Cancel(), Stop(100), Forward(10)]


async def test_goals_waiting_for_the_first_status_are_superseded() -> None:
    # The serial node's placeholders only: goto and goto_point wait for a real status.
    async with connected(ScriptedRobot(**DEFAULTS), map_targets=MAP_TARGETS) as (robot, fake):
        assert robot.awaiting_robot
        goto = await waiting(robot, lambda r: r.goto(FAR, timeout=WAIT))
        point = await waiting(robot, lambda r: r.goto_point(1.0, 2.0, timeout=WAIT))
        # Placeholders cannot show the robot stopped: the stop is sent, then unconfirmed.
        stopping = asyncio.ensure_future(robot.stop(timeout=0.2))
        # Real time here (a scripted robot over TCP): at once is within AT_ONCE.
        await superseded_at_once(goto, GoalCancelled, "stop()", within=AT_ONCE)
        await superseded_at_once(point, GoalCancelled, "stop()", within=AT_ONCE)
        with pytest.raises(StopUnconfirmed, match="only placeholder frames"):
            await stopping
        fake.set(**READY)
        await robot.wait_until(lambda s: s.navigating, timeout=WAIT)
        await flush(robot, fake)
        assert fake.received == [StopPatrol(), Cancel(), Stop(100), Stop(100)]


CANCELLABLE = ("forward", "goto")


@pytest.mark.parametrize("how", WAYS)
@pytest.mark.parametrize("name", CANCELLABLE)
async def test_a_stop_whose_own_caller_is_cancelled_at_once_still_supersedes(
    name: str, how: str
) -> None:
    call, error = SUPERSEDED[name]
    async with busy_robot() as (device, robot, log):
        task = await waiting(robot, call)
        await stop_waiting(how, robot.stop, after=0.0)  # the supersession came before any await
        await superseded_at_once(task, error, "stop()")
        device.busy(0)
        await robot.forward(10)
        await written(robot, log, Forward(10))
        assert moving(log) == [Forward(10)]


@pytest.mark.parametrize("how", WAYS)
@pytest.mark.parametrize("name", CANCELLABLE)
async def test_a_waiting_call_cancelled_by_its_caller_is_never_written(name: str, how: str) -> None:
    call, _error = SUPERSEDED[name]
    async with busy_robot() as (device, robot, log):
        await stop_waiting(how, lambda: call(robot), after=0.05)
        await robot.stop()
        device.busy(0)
        await robot.forward(10)
        await written(robot, log, Forward(10))
        assert moving(log) == [Forward(10)]


async def test_a_withdrawn_goal_cancels_the_goal_it_was_to_replace() -> None:
    # One write every 0.5 s: ``g RIGHT`` waits in the link's queue, where it already counts
    # as replacing goal FAR; withdrawn, it must not leave goal FAR driving unwatched.
    async with busy_robot(min_command_interval=PACING) as (device, robot, log):
        device.busy(0)
        first = asyncio.ensure_future(robot.goto(FAR, timeout=WAIT))
        await robot.wait_until(lambda s: s.target_num_id == FAR and s.goal_active, timeout=WAIT)
        second = await waiting(robot, lambda r: r.goto(RIGHT, timeout=WAIT))
        await robot.stop()
        # It ends once its cancel of goal FAR is written: one pacing interval after the stop.
        await superseded_at_once(second, GoalCancelled, "stop()", within=PACING)
        with pytest.raises(GoalCancelled):
            await first
        await robot.wait_until(lambda s: not s.goal_active, timeout=WAIT)
        await written(robot, log, Cancel())
        assert moving(log) == [Goto(FAR)]
