"""A goal goes on through a stale spell the link recovers from; a lost link ends it (issue 30, 5).

The simulated robot of galileo_async.testing on the virtual clock: ``device.mute()`` stops its
frames (the connection stays open, commands still arrive), ``device.unmute()`` sends them
again. With the link's defaults a silence makes the link STALE after 1 s and LOST after 5 s.
The goal is followed on through STALE (the awaiting call sees LinkStaleEvent and goes on),
fails with ConnectionLost at LOST, and is cancelled once frames show it still running.
"""

from __future__ import annotations

import asyncio
from typing import Any

import anyio
import pytest

import galileo_async as galileo
from galileo_async import ConnectionLost, LinkStale, LinkState, OperationTimeout, TargetStatus
from galileo_async.errors import GoalStalled
from galileo_async.events import AbandonedGoalCancelled, Event
from galileo_async.protocol import Cancel, Goto
from galileo_async.testing import simulated_robot

#: Virtual seconds any single wait may take before it fails.
WAIT = 120.0
#: Target 0 is one metre ahead; target 1 twelve metres (15 s at the simulator's 0.8 m/s).
TARGETS: tuple[tuple[float, float], ...] = ((1.0, 0.0), (12.0, 0.0))
NEAR, FAR = 0, 1
#: The link's defaults: stale after this silence, given up (LOST) after 5 of them.
STALE = 1.0
LOST = 5 * STALE
#: Virtual seconds between two status frames (30 Hz).
FRAME = 1 / 30


def now() -> float:
    return asyncio.get_running_loop().time()


def recorded(robot: galileo.Robot) -> list[Event]:
    """Every event of ``robot`` from now on, in order (a synchronous listener)."""
    events: list[Event] = []
    robot.add_event_listener(events.append)
    return events


def names(events: list[Event]) -> list[str]:
    return [event.name for event in events]


async def far_goal_working(robot: galileo.Robot) -> float:
    """Loop time of the first frame that shows the far goal working."""
    await robot.wait_until(
        lambda s: s.target_num_id == FAR and s.target_status == TargetStatus.WORKING,
        timeout=WAIT,
    )
    return now()


async def test_a_goal_goes_on_through_a_stale_spell() -> None:
    async with simulated_robot(targets=TARGETS) as (robot, device):
        events = recorded(robot)
        goal = asyncio.create_task(robot.goto(FAR, timeout=WAIT))
        await far_goal_working(robot)
        device.mute()
        await robot.wait_link(LinkState.STALE, timeout=WAIT)
        await device.advance(2 * STALE)  # 3 s without a frame: stale, not yet lost
        assert not goal.done()
        # A new command while stale is still refused before anything is sent.
        with pytest.raises(LinkStale, match="nothing was sent"):
            await robot.goto(NEAR, timeout=WAIT)
        device.unmute()
        result = await asyncio.wait_for(goal, WAIT)
        assert result.target_id == FAR
        assert device.pose.x == pytest.approx(12.0, abs=0.05)
    assert device.received() == [Goto(FAR)]  # no i 2 on the way
    assert names(events) == ["GoalAccepted", "LinkStale", "LinkRestored", "GoalReached"]


async def test_the_stall_clock_stops_while_the_link_is_stale() -> None:
    progress = 10.0
    async with simulated_robot(targets=TARGETS, progress_timeout=progress) as (robot, device):
        goal = asyncio.create_task(robot.goto(FAR, timeout=WAIT))
        accepted_at = await far_goal_working(robot)
        device.freeze()  # the robot makes no progress from here on
        await device.advance(3.0)
        device.mute()
        muted_at = now()
        await device.advance(4.0)  # stale after 1 s, back after 4 s of silence
        device.unmute()
        with anyio.fail_after(WAIT), pytest.raises(GoalStalled) as caught:
            await goal
        # Without the silence the goal would stall progress_timeout after acceptance; the
        # 4 s without frames (from the last frame to the first one back) do not count.
        silence = 4.0
        stalled_at = now()
        assert stalled_at - accepted_at == pytest.approx(progress + silence, abs=2 * FRAME)
        assert caught.value.stalled_for == pytest.approx(progress, abs=2 * FRAME)
        assert muted_at - accepted_at == pytest.approx(3.0, abs=FRAME)
    assert device.received() == [Goto(FAR), Cancel()]  # the stall's exit cancel


async def test_the_goal_is_accepted_after_a_stale_spell() -> None:
    async with simulated_robot(targets=TARGETS) as (robot, device):
        device.mute()  # silent from now on: the link is still fresh when g 1 goes out
        goal = asyncio.create_task(robot.goto(FAR, timeout=WAIT, accept_timeout=2.0))
        await device.next_command(Goto, timeout=WAIT)
        await device.advance(4.0)  # longer than accept_timeout, without a frame
        assert robot.link_state is LinkState.STALE
        assert not goal.done()
        device.unmute()
        assert (await asyncio.wait_for(goal, WAIT)).target_id == FAR
    assert device.received() == [Goto(FAR)]


async def test_a_lost_link_fails_the_goal_and_cancels_it_once_back() -> None:
    async with simulated_robot(targets=TARGETS) as (robot, device):
        events = recorded(robot)
        goal = asyncio.create_task(robot.goto(FAR, timeout=WAIT))
        await far_goal_working(robot)
        device.mute()
        muted_at = now()
        with anyio.fail_after(WAIT), pytest.raises(ConnectionLost):
            await goal
        assert now() - muted_at == pytest.approx(LOST, abs=FRAME)
        assert device.received() == [Goto(FAR)]  # a lost link carries no cancel
        assert device.status.target_status == TargetStatus.WORKING  # it drives on, unseen
        device.unmute()
        await robot.wait_link(LinkState.UP, timeout=WAIT)
        await robot.wait_until(lambda s: not s.goal_active, timeout=WAIT)
        assert device.received() == [Goto(FAR), Cancel()]
        abandoned = [e for e in events if isinstance(e, AbandonedGoalCancelled)]
        assert [e.target_id for e in abandoned] == [FAR]
    link_events = [name for name in names(events) if name.startswith(("Link", "Connection"))]
    assert link_events == ["LinkStale", "ConnectionLost", "ConnectionRestored"]


@pytest.mark.parametrize("how", ["timeout", "cancel"])
async def test_leaving_a_goal_while_stale_sends_the_cancel(how: str) -> None:
    async with simulated_robot(targets=TARGETS) as (robot, device):
        events = recorded(robot)
        options: dict[str, Any] = {"timeout": 3.0} if how == "timeout" else {}
        goal = asyncio.create_task(robot.goto(FAR, **options))
        called_at = now()
        await far_goal_working(robot)
        device.mute()
        await robot.wait_link(LinkState.STALE, timeout=WAIT)
        if how == "cancel":
            goal.cancel()
        expected = OperationTimeout if how == "timeout" else asyncio.CancelledError
        with anyio.fail_after(WAIT), pytest.raises(expected):
            await goal
        if how == "timeout":
            assert now() - called_at == pytest.approx(3.0)  # the overall timeout still counts
        # The stale link may still carry commands: the exit cancel went out, and stopped it.
        if Cancel() not in device.received():
            await device.next_command(Cancel, timeout=WAIT)
        device.unmute()
        await robot.wait_link(LinkState.UP, timeout=WAIT)
        await robot.wait_until(lambda s: not s.goal_active, timeout=WAIT)
        await device.advance(1.0)  # time for the abandoned goal's check: nothing to cancel
    assert device.received() == [Goto(FAR), Cancel()]
    assert not any(isinstance(e, AbandonedGoalCancelled) for e in events)


async def test_a_goal_that_arrived_unseen_is_reached_once_frames_are_back() -> None:
    async with simulated_robot(targets=((0.5, 0.0), (2.0, 0.0))) as (robot, device):
        events = recorded(robot)
        goal = asyncio.create_task(robot.goto(FAR, timeout=WAIT))
        await far_goal_working(robot)
        device.mute()
        await device.advance(LOST - STALE)  # the robot arrives meanwhile, unseen
        assert device.status.target_status == TargetStatus.FREE
        device.unmute()
        result = await asyncio.wait_for(goal, WAIT)
        assert result.target_id == FAR
        assert result.distance == 0.0
    assert device.received() == [Goto(FAR)]
    assert names(events)[-1] == "GoalReached"
