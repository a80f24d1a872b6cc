"""A goal that makes no progress ends with GoalStalled, cancel first (nav2's progress checker).

The Simulator over TCP loopback plays the robot, with the faults of issue 21 item 4: a dead
navigation stack behind a live serial node (``freeze_after``: the same status re-sent with a
live time_stamp) and a blocked robot (``block_after``: working, not moving).
"""

from __future__ import annotations

import contextlib
from collections.abc import AsyncIterator
from typing import Any

import anyio
import pytest
from sim_integration import WAIT, record_commands

import galileo_async as galileo
from galileo_async import GoalStalled, OperationTimeout, TargetStatus
from galileo_async.events import GoalStalledEvent
from galileo_async.protocol import AddTarget, Cancel, Command, Goto, ResetTargets
from galileo_async.sim import Simulator

#: Simulated seconds per real second: slow enough that progress_timeout below stays well
#: above the scheduling jitter of a loaded machine.
SPEED = 20.0
#: Real seconds without progress before a stall (10 simulated seconds).
PROGRESS = 0.5
#: Target 0 is 8 m ahead (a long straight trip); target 1 one metre ahead.
TARGETS = ((8.0, 0.0), (1.0, 0.0))
FAR, NEAR = 0, 1


@contextlib.asynccontextmanager
async def robot_and_log(
    *, progress: float | None = PROGRESS, **sim_options: Any
) -> AsyncIterator[tuple[galileo.Robot, list[tuple[Command, bool]]]]:
    """A navigating Robot on a Simulator over TCP, and the log of commands it received."""
    async with Simulator(speed=SPEED, targets=TARGETS, **sim_options) as sim:
        server = await sim.serve_tcp()
        url = f"socket://127.0.0.1:{server.sockets[0].getsockname()[1]}"
        async with galileo.connect(
            url, map_targets=len(TARGETS), progress_timeout=progress
        ) as robot:
            await robot.start_navigation(timeout=WAIT)
            yield robot, record_commands(sim)


async def wire(robot: galileo.Robot, log: list[tuple[Command, bool]], count: int) -> list[Command]:
    """The commands that reached the simulator, once at least ``count`` have (frame by frame)."""
    await robot.wait_until(lambda _status: len(log) >= count, timeout=WAIT)
    return [command for command, _busy in log]


async def next_stall(events: Any) -> GoalStalledEvent:
    with anyio.fail_after(WAIT):
        async for event in events:
            if isinstance(event, GoalStalledEvent):
                return event
    raise AssertionError("events ended without GoalStalledEvent")


@pytest.mark.parametrize("fault", ["freeze_after", "block_after"])
async def test_a_goal_without_progress_is_cancelled_then_fails_with_goal_stalled(
    fault: str,
) -> None:
    async with robot_and_log(**{fault: 1.0}) as (robot, log):
        events = robot.events()
        sent = robot.link.commands_sent
        with anyio.fail_after(WAIT), pytest.raises(GoalStalled) as caught:
            await robot.goto(FAR)
        # i 2 was written before the raise: two commands, g 0 then i 2.
        assert robot.link.commands_sent == sent + 2
        assert await wire(robot, log, 2) == [Goto(FAR), Cancel()]
        error = caught.value
        assert error.target_id == FAR
        assert error.stalled_for >= PROGRESS
        assert error.status is not None
        assert error.status.target_status == TargetStatus.WORKING
        event = await next_stall(events)
        assert (event.target_id, event.stalled_for) == (FAR, error.stalled_for)


async def test_goto_point_stalls_too() -> None:
    async with robot_and_log(block_after=1.0) as (robot, log):
        events = robot.events()
        with anyio.fail_after(WAIT), pytest.raises(GoalStalled) as caught:
            await robot.goto_point(6.0, 0.0)
        dynamic = len(TARGETS)
        assert caught.value.target_id == dynamic
        assert await wire(robot, log, 4) == [
            ResetTargets(),
            AddTarget(6.0, 0.0),
            Goto(dynamic),
            Cancel(),
        ]
        assert (await next_stall(events)).target_id == dynamic


async def test_a_slow_robot_that_keeps_moving_arrives() -> None:
    # 0.04 m/s: 0.1 m takes 2.5 simulated s (0.125 s), the trip 25 s (1.25 s), over twice
    # progress_timeout: only progress in each window keeps the goal alive.
    async with robot_and_log(max_speed=0.04) as (robot, log):
        with anyio.fail_after(WAIT):
            result = await robot.goto(NEAR)
        assert result.elapsed > 2 * PROGRESS
        assert Cancel() not in await wire(robot, log, 1)


async def test_paused_time_does_not_count() -> None:
    async with robot_and_log() as (robot, log):
        with anyio.fail_after(WAIT):
            async with anyio.create_task_group() as tasks:
                results: list[galileo.GoalResult] = []

                async def go() -> None:
                    results.append(await robot.goto(FAR))

                tasks.start_soon(go)
                await robot.wait_until(lambda s: s.target_status == TargetStatus.WORKING)
                await robot.pause()
                await anyio.sleep(2 * PROGRESS)
                await robot.resume()
        assert [result.target_id for result in results] == [FAR]
        assert Cancel() not in await wire(robot, log, 1)


@pytest.mark.parametrize("where", ["connect", "call"])
async def test_progress_timeout_none_never_stalls(where: str) -> None:
    # Blocked for good: without the check only the goal's own timeout ends it.
    progress = None if where == "connect" else PROGRESS
    async with robot_and_log(block_after=1.0, progress=progress) as (robot, log):
        options = {"progress_timeout": None} if where == "call" else {}
        with anyio.fail_after(WAIT), pytest.raises(OperationTimeout):
            await robot.goto(FAR, timeout=2 * PROGRESS, **options)
        assert await wire(robot, log, 2) == [Goto(FAR), Cancel()]  # the timeout's exit cancel
