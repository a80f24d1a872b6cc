"""The steps every Robot operation takes before it writes (docs/robot.md, Operations.send).

A busy robot holds an operation back; what it checked before the wait may have changed by
the time the robot is free, so the precondition is checked again and a follower looks at
the status as the command is written, not as the call began. The scripted robot plays the
firmware over TCP loopback.
"""

from __future__ import annotations

import asyncio
from typing import Any

import anyio
import pytest

from galileo_async import NotReady, TargetStatus
from galileo_async.models import AngleGoalStatus
from galileo_async.protocol import RotateTo
from tests.support.scripted_robot import ScriptedRobot, connected, nothing_was_sent_before_marker

STEP = 2.0  # upper bound for anything that should happen promptly


async def test_a_precondition_that_fails_during_busy_sends_nothing() -> None:
    working: dict[str, Any] = {
        "target_num_id": 1, "target_status": TargetStatus.WORKING, "busy_status": 1,
    }  # fmt: skip
    async with connected(ScriptedRobot(**working)) as (robot, fake):
        pausing = asyncio.ensure_future(robot.pause(timeout=STEP))
        await fake.frames(3)
        assert not pausing.done()  # held back by busy_status
        fake.set(target_status=TargetStatus.FREE, busy_status=0)  # the goal ended meanwhile
        with anyio.fail_after(STEP), pytest.raises(NotReady, match="the goal must be working"):
            await pausing
        await nothing_was_sent_before_marker(robot, fake)


async def rotate_then_done(fake: ScriptedRobot, command: Any) -> None:
    """A firmware that handles ``a``: angle_goal_status 0, then 1."""
    await fake.frames(2)
    fake.set(angle_goal_status=AngleGoalStatus.NOT_DONE)
    await fake.frames(2)
    fake.set(angle_goal_status=AngleGoalStatus.DONE)


async def test_rotate_to_judges_goals_from_the_status_as_it_writes() -> None:
    # A goal of another host ended while rotate_to waited out busy_status: it is over
    # before the 'a' is written, so it does not replace the rotation.
    async with connected(ScriptedRobot(busy_status=1)) as (robot, fake):
        fake.scripts[RotateTo] = rotate_then_done
        rotating = asyncio.ensure_future(robot.rotate_to(90, timeout=STEP))
        await fake.frames(3)
        assert not rotating.done()
        fake.set(target_num_id=4, target_status=TargetStatus.FREE, target_distance=0.0)
        await robot.wait_until(lambda s: s.target_num_id == 4, timeout=STEP)
        fake.set(busy_status=0)
        with anyio.fail_after(STEP):
            await rotating
        assert fake.of_type(RotateTo) == [RotateTo(90)]
