"""goto(N) while the robot already stands at target N: a result, not an accept timeout.

The firmware may finish such a goal within one 33 ms frame, so no frame shows it working
and target_num_id does not change. ALREADY_THERE_FRAMES frames in a row after the send
showing goal N free within arrive_tolerance, and no working frame, are the proof.
"""

from __future__ import annotations

import asyncio
import json
import sys

import anyio
import pytest

from galileo_async import AcceptTimeout, GoalResult, TargetStatus
from galileo_async.protocol import Cancel, Goto, Stop
from galileo_async.robot.goal import ALREADY_THERE_FRAMES
from tests.support.scripted_robot import ScriptedRobot, connected, drive, flush, ignore

#: Standing on target 3, the previous goal to it finished: what the firmware then shows.
AT_TARGET_3 = {"target_num_id": 3, "target_status": 0, "target_distance": 0.0}


async def test_goto_the_target_the_robot_stands_on_is_a_result() -> None:
    fake = ScriptedRobot(**AT_TARGET_3)
    fake.scripts[Goto] = ignore  # done within a frame: nothing on the wire changes
    async with connected(fake, accept_timeout=5.0) as (robot, _):
        with anyio.fail_after(2):  # far below accept_timeout: no AcceptTimeout was waited for
            result = await robot.goto(3, timeout=10)
        await flush(robot, fake)
    assert isinstance(result, GoalResult)
    assert result.already_there
    assert (result.target_id, result.distance) == (3, 0.0)
    assert result.status.target_status == TargetStatus.FREE
    assert fake.received == [Goto(3), Stop(100)]  # a finished goal is not cancelled


async def test_within_the_arrive_tolerance_counts_as_there() -> None:
    fake = ScriptedRobot(target_num_id=3, target_status=0, target_distance=0.2)
    fake.scripts[Goto] = ignore
    async with connected(fake, arrive_tolerance=0.3) as (robot, _):
        result = await robot.goto(3, timeout=10)
    assert result.already_there
    assert result.distance == pytest.approx(0.2)


async def test_a_normal_arrival_is_not_already_there() -> None:
    async with connected() as (robot, _):
        result = await robot.goto(3, timeout=5)
    assert not result.already_there


async def test_a_working_frame_within_the_window_makes_it_a_normal_goal() -> None:
    # The firmware starts the goal a few frames late: it is followed to its end as usual.
    async def late(fake: ScriptedRobot, command: Goto) -> None:
        await fake.frames(ALREADY_THERE_FRAMES // 2)
        await drive(fake, command.target_id)

    fake = ScriptedRobot(**AT_TARGET_3)
    fake.scripts[Goto] = late
    async with connected(fake) as (robot, _):
        result = await robot.goto(3, timeout=5)
    assert not result.already_there
    assert result.elapsed > 0


async def test_free_far_from_the_target_is_still_an_accept_timeout() -> None:
    # The last goal to 3 stopped short: free at 3 but far away is not "there".
    fake = ScriptedRobot(target_num_id=3, target_status=0, target_distance=2.0)
    fake.scripts[Goto] = ignore
    async with connected(fake, accept_timeout=0.3) as (robot, _):
        with pytest.raises(AcceptTimeout):
            await robot.goto(3, timeout=5)
        await fake.command(Cancel)


async def test_at_another_target_is_still_an_accept_timeout() -> None:
    fake = ScriptedRobot(target_num_id=2, target_status=0, target_distance=0.0)
    fake.scripts[Goto] = ignore
    async with connected(fake, accept_timeout=0.3) as (robot, _):
        with pytest.raises(AcceptTimeout):
            await robot.goto(3, timeout=5)


async def test_cancelling_while_counting_frames_sends_cancel_and_leaves_nothing() -> None:
    fake = ScriptedRobot(**AT_TARGET_3)
    fake.scripts[Goto] = ignore
    async with connected(fake) as (robot, _):
        task = asyncio.create_task(robot.goto(3, timeout=5))
        await fake.command(Goto)
        task.cancel()
        with pytest.raises(asyncio.CancelledError):
            await task
        await fake.command(Cancel)


@pytest.mark.parametrize("json_output", [False, True])
async def test_cli_goto_says_the_robot_was_already_there(json_output: bool) -> None:
    fake = ScriptedRobot(**AT_TARGET_3)
    fake.scripts[Goto] = ignore
    await fake.start()
    try:
        process = await asyncio.create_subprocess_exec(
            sys.executable, "-m", "galileo_async", "-p", fake.url,
            *(["--json"] if json_output else []), "goto", "3",
            stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE,
        )  # fmt: skip
        out, err = await asyncio.wait_for(process.communicate(), 60)
    finally:
        await fake.close()
    assert process.returncode == 0, err.decode()
    if json_output:
        assert json.loads(out)["already_there"] is True
    else:
        assert "(it was already there)" in out.decode()
