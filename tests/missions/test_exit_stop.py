"""The one exit stop of missions, schedules and offloaded chains: it completes whatever
cancels its caller, logs a failed stop instead of raising it, and leaves a closed robot alone."""

from __future__ import annotations

import asyncio
import logging
from typing import Any

import pytest

from galileo_async.errors import GalileoConnectionError, GoalCancelled
from galileo_async.missions.exit_stop import EXIT_STOP_TIMEOUT, exit_stop
from galileo_async.robot.stopping import in_motion
from galileo_async.testing import simulated_robot

pytestmark = pytest.mark.timeout(60)


class _FakeRobot:
    """Only what exit_stop reads: ``closed`` and ``stop``."""

    def __init__(self, *, closed: bool = False, fails: bool = False) -> None:
        self.closed = closed
        self.fails = fails
        self.stops: list[float | None] = []

    async def stop(self, brake: int = 0, *, timeout: float | None = None) -> Any:
        self.stops.append(timeout)
        if self.fails:
            raise GalileoConnectionError("link lost")


async def test_the_stop_completes_while_its_caller_is_cancelled_again_and_again() -> None:
    async with simulated_robot() as (robot, _):
        goal = asyncio.ensure_future(robot.goto(2))
        await asyncio.sleep(3.0)  # virtual clock: the goal is under way
        assert robot.status is not None
        assert in_motion(robot.status)
        stopping = asyncio.ensure_future(exit_stop(robot, "the test's exit stop"))
        for _ in range(5):
            await asyncio.sleep(0)
            stopping.cancel()
        with pytest.raises(asyncio.CancelledError):
            await stopping
        assert robot.status is not None
        assert in_motion(robot.status) == ()
        with pytest.raises(GoalCancelled):
            await goal


async def test_a_failed_stop_is_logged_not_raised(caplog: pytest.LogCaptureFixture) -> None:
    robot = _FakeRobot(fails=True)
    with caplog.at_level(logging.WARNING, "galileo_async.missions.exit_stop"):
        await exit_stop(robot, "the test's exit stop")  # type: ignore[arg-type]
    assert robot.stops == [EXIT_STOP_TIMEOUT]
    assert "the test's exit stop failed: link lost" in caplog.text


async def test_a_closed_robot_is_left_alone() -> None:
    robot = _FakeRobot(closed=True)
    await exit_stop(robot, "the test's exit stop")  # type: ignore[arg-type]
    assert robot.stops == []
