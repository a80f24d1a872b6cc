"""A goal's exit cancel never cancels the goal started after it (DESIGN.md "Goal exits").

A simulated_robot() on the virtual clock plays the robot; ``record_commands`` logs what
reached it, in wire order. Whatever way goto(3) is left, the goto(0) started right after
succeeds, and on the wire the old goal's ``i 2`` either comes before ``g 0`` or is not
sent at all.
"""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import AsyncIterator, Awaitable, Callable
from typing import Any

import anyio
import pytest

import galileo_async as galileo
from galileo_async import TargetStatus
from galileo_async.protocol import Cancel, Command, Goto, Stop
from galileo_async.state import StatusStore
from galileo_async.testing import simulated_robot
from galileo_async.transports import Link, StreamChannel
from tests.support.fake_device import MemoryConnector
from tests.support.sim_integration import WAIT, record_commands, time_limit

#: Goal 3 is far away (a long trip to interrupt); goal 0 is near.
TARGETS: tuple[tuple[float, float], ...] = ((1.5, 0.0), (0.0, -2.0), (-2.0, 0.0), (30.0, 0.0))
FAR, NEAR = 3, 0


@contextlib.asynccontextmanager
async def robot_and_log() -> AsyncIterator[tuple[galileo.Robot, list[tuple[Command, bool]]]]:
    """A navigating Robot on a simulated robot, and the log of commands it received."""
    async with simulated_robot(targets=TARGETS, navigating=False) as (robot, device):
        await robot.start_navigation(timeout=WAIT)
        log = record_commands(device.simulator)
        yield robot, log


async def far_goal_working(robot: galileo.Robot) -> None:
    await robot.wait_until(
        lambda s: s.target_num_id == FAR and s.target_status == TargetStatus.WORKING,
        timeout=WAIT,
    )


def assert_exit_cancel_not_after_the_new_goal(log: list[tuple[Command, bool]]) -> None:
    wire = [command for command, _busy in log]
    assert wire[0] == Goto(FAR)
    assert wire[1:] in ([Cancel(), Goto(NEAR)], [Goto(NEAR)]), wire


async def test_cancelled_task_then_a_new_goal_task_at_once() -> None:
    # The case: the old task handles its cancellation while the new task starts.
    async with robot_and_log() as (robot, log):
        old = asyncio.create_task(robot.goto(FAR))
        await far_goal_working(robot)
        old.cancel()
        new = asyncio.create_task(robot.goto(NEAR, timeout=WAIT))
        with pytest.raises(asyncio.CancelledError):
            await old
        result = await new
    assert result.target_id == NEAR
    assert_exit_cancel_not_after_the_new_goal(log)


async def test_cancelled_task_then_a_new_goal_in_the_same_turn() -> None:
    async with robot_and_log() as (robot, log):
        old = asyncio.create_task(robot.goto(FAR))
        await far_goal_working(robot)
        old.cancel()
        result = await robot.goto(NEAR, timeout=WAIT)
        with pytest.raises((asyncio.CancelledError, galileo.GoalCancelled)):
            await old
    assert result.target_id == NEAR
    assert_exit_cancel_not_after_the_new_goal(log)


async def test_cancelled_task_then_a_new_goal_task_one_turn_later() -> None:
    # The old task has queued its exit cancel when the new goal starts.
    async with robot_and_log() as (robot, log):
        old = asyncio.create_task(robot.goto(FAR))
        await far_goal_working(robot)
        old.cancel()
        await asyncio.sleep(0)
        new = asyncio.create_task(robot.goto(NEAR, timeout=WAIT))
        with pytest.raises(asyncio.CancelledError):
            await old
        result = await new
    assert result.target_id == NEAR
    assert_exit_cancel_not_after_the_new_goal(log)


def _leave_by_cancel_scope(goal: Awaitable[Any]) -> Awaitable[None]:
    async def run() -> None:
        with anyio.CancelScope() as scope:
            asyncio.get_running_loop().call_soon(scope.cancel)
            await goal

    return run()


def _leave_by_move_on_after(goal: Awaitable[Any]) -> Awaitable[None]:
    async def run() -> None:
        with anyio.move_on_after(0):
            await goal

    return run()


def _leave_by_fail_after(goal: Awaitable[Any]) -> Awaitable[None]:
    async def run() -> None:
        with contextlib.suppress(TimeoutError), anyio.fail_after(0):
            await goal

    return run()


def _leave_by_asyncio_timeout(goal: Awaitable[Any]) -> Awaitable[None]:
    async def run() -> None:
        with contextlib.suppress(TimeoutError):
            async with time_limit(0):
                await goal

    return run()


class SiblingFailed(Exception):
    """The failure of a task next to the goal in a task group."""


def _leave_by_failing_sibling(goal: Awaitable[Any]) -> Awaitable[None]:
    async def follow() -> None:
        await goal

    async def sibling() -> None:
        await asyncio.sleep(0)
        raise SiblingFailed

    async def run() -> None:
        with pytest.raises(Exception, match="TaskGroup") as caught:  # noqa: PT012
            async with anyio.create_task_group() as group:
                group.start_soon(follow)
                group.start_soon(sibling)
        assert caught.group_contains(SiblingFailed)

    return run()


LEAVE: dict[str, Callable[[Awaitable[Any]], Awaitable[None]]] = {
    "cancel_scope": _leave_by_cancel_scope,
    "move_on_after": _leave_by_move_on_after,
    "fail_after": _leave_by_fail_after,
    "asyncio_timeout": _leave_by_asyncio_timeout,
    "failing_sibling": _leave_by_failing_sibling,
}


@pytest.mark.parametrize("leave", list(LEAVE.values()), ids=list(LEAVE))
async def test_goal_left_by_a_cancel_scope_then_a_new_goal(
    leave: Callable[[Awaitable[Any]], Awaitable[None]],
) -> None:
    async with robot_and_log() as (robot, log):
        old = asyncio.create_task(robot.goto(FAR))
        await far_goal_working(robot)
        old.cancel()  # the robot drives to 3 with nobody waiting: the next goal takes over
        with pytest.raises(asyncio.CancelledError):
            await old
        log.clear()
        await leave(robot.goto(FAR))
        result = await robot.goto(NEAR, timeout=WAIT)
    assert result.target_id == NEAR
    wire = [command for command, _busy in log]
    assert wire[-1] == Goto(NEAR)
    assert Cancel() not in wire[wire.index(Goto(NEAR)) :]


# --- the writer: enqueue is FIFO and synchronous; a later goal drops a queued exit cancel --


async def in_memory_link() -> tuple[MemoryConnector, Link]:
    connector = MemoryConnector()
    link = Link(StreamChannel(connector), StatusStore(), min_command_interval=0.01)
    await link.open()
    return connector, link


async def test_a_goal_queued_after_an_exit_cancel_drops_it() -> None:
    connector, link = await in_memory_link()
    try:
        first = link.enqueue(Stop(100))
        exit_cancel = link.enqueue(Cancel(), superseded_by=(Goto,))
        goal = link.enqueue(Goto(0))
        assert await asyncio.wait_for(asyncio.gather(first, exit_cancel, goal), WAIT) == [
            True,
            False,
            True,
        ]
        assert [data for _, data in connector.transport.writes] == [
            galileo.protocol.encode(Stop(100)),
            galileo.protocol.encode(Goto(0)),
        ]
    finally:
        await link.close()


async def test_an_exit_cancel_written_before_the_goal_stays_first() -> None:
    connector, link = await in_memory_link()
    try:
        exit_cancel = link.enqueue(Cancel(), superseded_by=(Goto,))
        assert await asyncio.wait_for(exit_cancel, WAIT) is True
        other = link.enqueue(Stop(100))  # not a goal: the cancel would stay queued before it
        goal = link.enqueue(Goto(0))
        assert await asyncio.wait_for(asyncio.gather(other, goal), WAIT) == [True, True]
        assert [data for _, data in connector.transport.writes] == [
            galileo.protocol.encode(Cancel()),
            galileo.protocol.encode(Stop(100)),
            galileo.protocol.encode(Goto(0)),
        ]
    finally:
        await link.close()


async def test_enqueue_on_a_closed_link_raises_before_queueing() -> None:
    _connector, link = await in_memory_link()
    await link.close()
    with pytest.raises(galileo.ConnectionLost):
        link.enqueue(Cancel())
