"""A goal that makes no progress ends with GoalStalled, cancel first (nav2's progress checker).

The simulated robot of galileo_async.testing plays the robot on a virtual clock, with the
faults of issue 21 item 4: a dead navigation stack behind a live serial node
(``freeze_after`` / ``device.freeze()``: the same status re-sent with a live time_stamp)
and a blocked robot (``block_after``: working, not moving). Times are virtual seconds, so
the stall is asserted to the frame.
"""

from __future__ import annotations

import asyncio
from typing import Any

import anyio
import pytest

import galileo_async as galileo
from galileo_async import GoalStalled, OperationTimeout, TargetStatus
from galileo_async.events import GoalStalledEvent
from galileo_async.protocol import AddTarget, Cancel, Command, Goto, ResetTargets
from galileo_async.testing import SimulatedDevice

#: Virtual seconds without progress before a stall.
PROGRESS = 10.0
#: Bound, in virtual seconds, on every wait expected to succeed (the longest trip is 25 s
#: plus 20 s paused).
WAIT = 120.0
#: Target 0 is 8 m ahead (a long straight trip); target 1 one metre ahead.
TARGETS = ((8.0, 0.0), (1.0, 0.0))
FAR, NEAR = 0, 1
#: Virtual seconds the robot needs for PROGRESS_RADIUS (0.1 m) at its top speed (0.8 m/s).
STEP_TIME = 0.1 / 0.8
#: Virtual seconds between two status frames (30 Hz).
FRAME = 1 / 30


def sim(progress: float | None = PROGRESS, **sim_options: Any) -> pytest.MarkDecorator:
    """The simulated robot behind galileo_robot: TARGETS, ``progress``, faults."""
    return pytest.mark.galileo_sim(
        targets=TARGETS, progress_timeout=progress, sim_options=sim_options
    )


pytestmark = sim()


def now() -> float:
    return asyncio.get_running_loop().time()


async def wire(robot: galileo.Robot, device: SimulatedDevice, count: int) -> list[Command]:
    """The commands the robot received, once at least ``count`` have (frame by frame)."""
    await robot.wait_until(lambda _status: len(device.commands) >= count, timeout=WAIT)
    return device.received()


async def working(robot: galileo.Robot, target_id: int) -> float:
    """Loop time of the first frame showing goal ``target_id`` working (its acceptance)."""
    await robot.wait_until(
        lambda s: s.target_num_id == target_id and s.target_status == TargetStatus.WORKING,
        timeout=WAIT,
    )
    return now()


async def next_stall(events: Any) -> GoalStalledEvent:
    with anyio.fail_after(WAIT):
        async for event in events:
            if isinstance(event, GoalStalledEvent):
                return event
    raise AssertionError("events ended without GoalStalledEvent")


FAULTS = ("freeze_after", "block_after")


@pytest.mark.parametrize(
    "fault", [pytest.param(name, marks=sim(**{name: 1.0}), id=name) for name in FAULTS]
)
async def test_a_goal_without_progress_is_cancelled_then_fails_with_goal_stalled(
    fault: str, galileo_robot: galileo.Robot, galileo_device: SimulatedDevice
) -> None:
    robot, device = galileo_robot, galileo_device
    events = robot.events()
    sent = robot.link.commands_sent
    goal = asyncio.create_task(robot.goto(FAR))
    accepted_at = await working(robot, FAR)
    with anyio.fail_after(WAIT), pytest.raises(GoalStalled) as caught:
        await goal
    stalled_at = now()
    # i 2 was written before the raise: two commands, g 0 then i 2.
    assert robot.link.commands_sent == sent + 2
    assert await wire(robot, device, 2) == [Goto(FAR), Cancel()]
    error = caught.value
    assert error.target_id == FAR
    assert error.stalled_for == pytest.approx(PROGRESS)
    # The robot moved until the fault, 1 s into the goal, then not one step more: the stall
    # comes progress_timeout after its last step of progress, seen in the last frame.
    fault_at = accepted_at + 1.0
    assert fault_at + PROGRESS - STEP_TIME - FRAME <= stalled_at <= fault_at + PROGRESS
    assert error.status is not None
    assert error.status.target_status == TargetStatus.WORKING
    event = await next_stall(events)
    assert (event.target_id, event.stalled_for) == (FAR, error.stalled_for)


async def test_a_goal_that_never_moves_stalls_exactly_progress_timeout_after_acceptance(
    galileo_robot: galileo.Robot, galileo_device: SimulatedDevice
) -> None:
    robot, device = galileo_robot, galileo_device
    goal = asyncio.create_task(robot.goto(FAR))
    accepted_at = await working(robot, FAR)
    device.freeze()  # the navigation stack dies at once: the robot never moves 0.1 m
    with anyio.fail_after(WAIT), pytest.raises(GoalStalled) as caught:
        await goal
    assert now() - accepted_at == pytest.approx(PROGRESS)
    assert caught.value.stalled_for == pytest.approx(PROGRESS)
    assert await wire(robot, device, 2) == [Goto(FAR), Cancel()]


@sim(block_after=1.0)
async def test_goto_point_stalls_too(
    galileo_robot: galileo.Robot, galileo_device: SimulatedDevice
) -> None:
    robot, device = galileo_robot, galileo_device
    events = robot.events()
    with anyio.fail_after(WAIT), pytest.raises(GoalStalled) as caught:
        await robot.goto_point(6.0, 0.0)
    dynamic = len(TARGETS)
    assert caught.value.target_id == dynamic
    assert caught.value.stalled_for == pytest.approx(PROGRESS)
    assert await wire(robot, device, 4) == [
        ResetTargets(),
        AddTarget(6.0, 0.0),
        Goto(dynamic),
        Cancel(),
    ]
    assert (await next_stall(events)).target_id == dynamic


@sim(max_speed=0.04)
async def test_a_slow_robot_that_keeps_moving_arrives(
    galileo_robot: galileo.Robot, galileo_device: SimulatedDevice
) -> None:
    # 0.04 m/s: 0.1 m takes 2.5 s, the trip 25 s, over twice progress_timeout: only
    # progress in each window keeps the goal alive.
    robot, device = galileo_robot, galileo_device
    with anyio.fail_after(WAIT):
        result = await robot.goto(NEAR)
    assert result.elapsed > 2 * PROGRESS
    assert Cancel() not in await wire(robot, device, 1)


async def test_paused_time_does_not_count(
    galileo_robot: galileo.Robot, galileo_device: SimulatedDevice
) -> None:
    robot, device = galileo_robot, galileo_device
    with anyio.fail_after(WAIT):
        async with anyio.create_task_group() as tasks:
            results: list[galileo.GoalResult] = []

            async def go() -> None:
                results.append(await robot.goto(FAR))

            tasks.start_soon(go)
            await working(robot, FAR)
            await robot.pause()
            await anyio.sleep(2 * PROGRESS)
            await robot.resume()
    assert [result.target_id for result in results] == [FAR]
    assert results[0].elapsed > 2 * PROGRESS  # the pause fell inside the goal
    assert Cancel() not in await wire(robot, device, 1)


@pytest.mark.parametrize(
    "where",
    [
        pytest.param("connect", marks=sim(progress=None, block_after=1.0), id="connect"),
        pytest.param("call", marks=sim(block_after=1.0), id="call"),
    ],
)
async def test_progress_timeout_none_never_stalls(
    where: str, galileo_robot: galileo.Robot, galileo_device: SimulatedDevice
) -> None:
    # Blocked for good: without the check only the goal's own timeout ends it.
    robot, device = galileo_robot, galileo_device
    assert robot.progress_timeout == (None if where == "connect" else PROGRESS)
    options: dict[str, Any] = {"progress_timeout": None} if where == "call" else {}
    called_at = now()
    with anyio.fail_after(WAIT), pytest.raises(OperationTimeout):
        await robot.goto(FAR, timeout=2 * PROGRESS, **options)
    assert now() - called_at == pytest.approx(2 * PROGRESS)  # the timeout, to the frame
    assert await wire(robot, device, 2) == [Goto(FAR), Cancel()]  # the timeout's exit cancel
