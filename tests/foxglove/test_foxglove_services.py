"""A goto service's wait for acceptance, on a stand-in robot: which acceptance counts, and
the cancel after a goal never shown accepted."""

from __future__ import annotations

import asyncio
from collections.abc import Callable
from typing import Any

import pytest

from galileo_async.errors import AcceptTimeout, GoalRejected
from galileo_async.events import Event, GoalAccepted
from galileo_async.foxglove.services import _until_accepted


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


async def test_a_goal_never_shown_accepted_is_cancelled() -> None:
    robot = StandIn()

    async def goto() -> Any:
        raise AcceptTimeout("goal 3 not accepted within 5 s", target_id=3)

    with pytest.raises(AcceptTimeout):
        await _until_accepted(robot, goto(), 3)  # type: ignore[arg-type]
    assert robot.cancels == 1
    assert robot.listeners == []


async def test_a_rejected_goal_sends_nothing_more() -> None:
    robot = StandIn()

    async def goto() -> Any:
        raise GoalRejected("the robot rejected goal 9", target_id=9)

    with pytest.raises(GoalRejected):
        await _until_accepted(robot, goto(), 9)  # type: ignore[arg-type]
    assert robot.cancels == 0
