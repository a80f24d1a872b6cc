"""A goto service's wait for acceptance: which acceptance counts (a stand-in robot), and a
goal never shown accepted cancelled by goto's own exit (a scripted robot)."""

from __future__ import annotations

import asyncio
from collections.abc import Callable
from typing import Any

import pytest

from galileo_async.errors import AcceptTimeout, GoalRejected
from galileo_async.events import Event, GoalAccepted
from galileo_async.foxglove.services import _until_accepted
from galileo_async.protocol import Cancel, Goto
from tests.support.scripted_robot import ScriptedRobot, connected, ignore


class StandIn:
    """The Robot calls _until_accepted makes: event listeners and cancel()."""

    def __init__(self) -> None:
        self.listeners: list[Callable[[Event], None]] = []
        self.cancels = 0

    def add_event_listener(self, listener: Callable[[Event], None]) -> None:
        self.listeners.append(listener)

    def remove_event_listener(self, listener: Callable[[Event], None]) -> None:
        self.listeners.remove(listener)

    def emit(self, event: Event) -> None:
        for listener in list(self.listeners):
            listener(event)

    async def cancel(self) -> None:
        self.cancels += 1


async def test_only_the_goals_own_acceptance_answers_and_the_goto_is_left() -> None:
    robot = StandIn()
    left = asyncio.Event()

    async def goto() -> None:
        try:
            await asyncio.Event().wait()
        finally:
            left.set()

    waiting = asyncio.ensure_future(_until_accepted(robot, goto(), 3))  # type: ignore[arg-type]
    await asyncio.sleep(0)
    robot.emit(GoalAccepted(status=None, target_id=5))  # another caller's goal
    await asyncio.sleep(0)
    assert not waiting.done()
    robot.emit(GoalAccepted(status=None, target_id=3))
    assert await waiting == {"accepted": True, "target": 3, "arrived": False}
    assert left.is_set()  # the goto's task ended with the call
    assert robot.listeners == []
    assert robot.cancels == 0  # nothing sent once accepted


async def test_a_goal_never_shown_accepted_is_cancelled_by_gotos_own_exit() -> None:
    fake = ScriptedRobot()
    fake.scripts[Goto] = ignore  # written, never shown accepted
    async with connected(fake, accept_timeout=0.2) as (robot, _):
        with pytest.raises(AcceptTimeout):
            await _until_accepted(robot, robot.goto(3, cancel_on_exit=False), 3)
        await fake.command(Cancel)
    assert fake.received[:2] == [Goto(3), Cancel()]


async def test_a_call_ended_before_the_acceptance_leaves_no_goal_to_start_later() -> None:
    """The service's time limit or the server closing cancels the call mid-wait."""
    fake = ScriptedRobot()
    fake.scripts[Goto] = ignore
    async with connected(fake) as (robot, _):
        call = asyncio.ensure_future(_until_accepted(robot, robot.goto(3, cancel_on_exit=False), 3))
        await fake.command(Goto)
        call.cancel()
        with pytest.raises(asyncio.CancelledError):
            await call
        await fake.command(Cancel)
    assert fake.received[:2] == [Goto(3), Cancel()]


async def test_a_rejected_goal_sends_nothing_more() -> None:
    robot = StandIn()

    async def goto() -> Any:
        raise GoalRejected("the robot rejected goal 9", target_id=9)

    with pytest.raises(GoalRejected):
        await _until_accepted(robot, goto(), 9)  # type: ignore[arg-type]
    assert robot.cancels == 0
