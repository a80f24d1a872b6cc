"""goto and goto_point against a scripted fake robot over TCP loopback (DESIGN.md "Semantics")."""

from __future__ import annotations

import asyncio
import math
from typing import Any

import anyio
import pytest

from galileo_async import (
    AcceptTimeout,
    ConnectionLost,
    GalileoTimeout,
    GoalAborted,
    GoalCancelled,
    GoalRejected,
    GoalResult,
    InvalidArgument,
    NotReady,
    OperationTimeout,
    TargetStatus,
)
from galileo_async import events as ev
from galileo_async.protocol import Cancel, Goto, Stop
from tests.support.scripted_robot import (
    ENDLESS,
    REACTION_FRAMES,
    ScriptedRobot,
    connected,
    drive,
    flush,
    ignore,
    nothing_was_sent_before_marker,
    working,
)

# --- completion ------------------------------------------------------------------------


async def test_goto_arrives_and_returns_result() -> None:
    async with connected() as (robot, fake):
        result = await robot.goto(3, timeout=5)
    assert isinstance(result, GoalResult)
    assert result.target_id == 3
    assert result.distance == 0.0
    assert result.elapsed > 0
    assert result.status.target_status == TargetStatus.FREE
    assert fake.received == [Goto(3)]


async def test_stale_arrived_frames_after_the_command_are_not_an_arrival() -> None:
    # The previous goal went to 3 and arrived: right after `g 3` the cached status
    # still shows (3, free, 0.0), which must not count as this goal arriving.
    marks: dict[str, int] = {}

    async def slow_goto(fake: ScriptedRobot, command: Goto) -> None:
        await fake.frames(5)
        marks["working_from"] = fake.frames_sent + 1
        await drive(fake, command.target_id)

    fake = ScriptedRobot(target_num_id=3, target_status=0, target_distance=0.0)
    fake.scripts[Goto] = slow_goto
    async with connected(fake) as (robot, _):
        result = await robot.goto(3, timeout=5)
    assert result.status.time_stamp is not None
    assert result.status.time_stamp > marks["working_from"]


async def test_free_within_tolerance_is_an_arrival() -> None:
    async def stops_close(fake: ScriptedRobot, command: Goto) -> None:
        fake.set(target_num_id=3, target_status=1, target_distance=1.0)
        await fake.frames(3)
        fake.set(target_status=0, target_distance=0.25)

    fake = ScriptedRobot()
    fake.scripts[Goto] = stops_close
    async with connected(fake, arrive_tolerance=0.3) as (robot, _):
        result = await robot.goto(3, timeout=5)
    assert result.distance == pytest.approx(0.25)


async def test_paused_is_not_an_end() -> None:
    seen: list[str] = []

    async def with_pause(fake: ScriptedRobot, command: Goto) -> None:
        fake.set(target_num_id=3, target_status=1, target_distance=2.0)
        await fake.frames(3)
        fake.set(target_status=TargetStatus.PAUSED)
        await fake.frames(10)
        seen.append("paused")
        fake.set(target_status=TargetStatus.WORKING, target_distance=1.0)
        await fake.frames(3)
        fake.set(target_status=TargetStatus.FREE, target_distance=0.0)

    fake = ScriptedRobot()
    fake.scripts[Goto] = with_pause
    async with connected(fake) as (robot, _):
        result = await robot.goto(3, timeout=5)
    assert seen == ["paused"]
    assert result.distance == 0.0


async def test_finished_between_two_frames_counts_when_the_id_changed() -> None:
    async def instant(fake: ScriptedRobot, command: Goto) -> None:
        await fake.frames(REACTION_FRAMES)
        fake.set(target_num_id=command.target_id, target_status=0, target_distance=0.0)

    fake = ScriptedRobot(target_num_id=1, target_status=0, target_distance=0.0)
    fake.scripts[Goto] = instant
    async with connected(fake) as (robot, _):
        result = await robot.goto(4, timeout=5)
    assert result.target_id == 4


async def test_sending_the_running_goal_again_survives_the_restart() -> None:
    # The firmware cancels the running goal before starting the new one (docs/protocol.md §2.b):
    # a frame showing it cancelled must not end the new goal.
    async def restart(fake: ScriptedRobot, command: Goto) -> None:
        await fake.frames(REACTION_FRAMES)
        fake.set(target_num_id=-1, target_status=0)
        await fake.frames(2)
        await drive(fake, command.target_id)

    fake = ScriptedRobot(target_num_id=3, target_status=1, target_distance=5.0)
    fake.scripts[Goto] = restart
    async with connected(fake) as (robot, _):
        result = await robot.goto(3, timeout=5)
    assert result.distance == 0.0


# --- rejection and abort ---------------------------------------------------------------


async def test_rejection_as_minus_one_with_the_id_unchanged() -> None:
    # Real firmware: invalid id -> target_status -1, target_num_id not updated (§2.b).
    fake = ScriptedRobot(target_num_id=2, target_status=0, target_distance=0.0, map_targets=10)
    async with connected(fake) as (robot, _):
        with pytest.raises(GoalRejected) as caught:
            await robot.goto(99, timeout=5)
        await flush(robot, fake)
    assert caught.value.target_id == 99
    assert caught.value.status is not None
    assert caught.value.status.target_num_id == 2
    assert caught.value.status.target_status == TargetStatus.INVALID
    assert fake.received == [Goto(99), Stop(100)]  # a rejected goal is not cancelled


async def test_a_stale_error_from_before_the_command_is_not_a_rejection() -> None:
    # The previous goal was rejected: the first frames after `g 3` still show -1.
    fake = ScriptedRobot(target_num_id=2, target_status=-1, target_distance=-1.0)
    async with connected(fake) as (robot, _):
        result = await robot.goto(3, timeout=5)
    assert result.target_id == 3


async def test_rejection_as_document_error_three() -> None:
    async def document_reject(fake: ScriptedRobot, command: Goto) -> None:
        await fake.frames(REACTION_FRAMES)
        fake.set(target_num_id=command.target_id, target_status=TargetStatus.ERROR)

    fake = ScriptedRobot()
    fake.scripts[Goto] = document_reject
    async with connected(fake) as (robot, _):
        with pytest.raises(GoalRejected) as caught:
            await robot.goto(42, timeout=5)
    assert caught.value.status is not None
    assert caught.value.status.target_status == TargetStatus.ERROR


async def test_rejection_invisible_behind_minus_one_times_out_with_a_hint() -> None:
    # Fresh robot: status already -1; a rejected id changes nothing on the wire.
    fake = ScriptedRobot(target_num_id=-1, target_status=-1, map_targets=10)
    async with connected(fake) as (robot, _):
        with pytest.raises(AcceptTimeout) as caught:
            await robot.goto(99, timeout=5, accept_timeout=0.2)
        await fake.command(Cancel)  # a timed-out goal is cancelled on the way out
    assert isinstance(caught.value, TimeoutError)
    assert "-1" in str(caught.value)
    assert caught.value.target_id == 99


async def test_lost_goal_command_is_an_accept_timeout() -> None:
    fake = ScriptedRobot()
    fake.scripts[Goto] = ignore
    async with connected(fake, accept_timeout=0.2) as (robot, _):
        with pytest.raises(AcceptTimeout):
            await robot.goto(3, timeout=5)


async def test_free_far_from_the_target_is_an_abort() -> None:
    async def gives_up(fake: ScriptedRobot, command: Goto) -> None:
        fake.set(target_num_id=3, target_status=1, target_distance=3.0)
        await fake.frames(5)
        fake.set(target_status=0, target_distance=2.0)

    fake = ScriptedRobot()
    fake.scripts[Goto] = gives_up
    async with connected(fake) as (robot, _):
        with pytest.raises(GoalAborted) as caught:
            await robot.goto(3, timeout=5)
    assert caught.value.distance == pytest.approx(2.0)
    assert caught.value.target_id == 3


async def test_error_while_moving_is_a_rejection() -> None:
    async def fails(fake: ScriptedRobot, command: Goto) -> None:
        fake.set(target_num_id=3, target_status=1, target_distance=3.0)
        await fake.frames(3)
        fake.set(target_status=TargetStatus.INVALID)

    fake = ScriptedRobot()
    fake.scripts[Goto] = fails
    async with connected(fake) as (robot, _):
        with pytest.raises(GoalRejected):
            await robot.goto(3, timeout=5)


# --- cancellation and preemption -------------------------------------------------------


async def test_newer_goal_of_the_same_robot_preempts_the_older() -> None:
    async with connected(ScriptedRobot(**ENDLESS)) as (robot, fake):
        first = asyncio.create_task(robot.goto(3))
        await working(robot, 3)
        second = asyncio.create_task(robot.goto(4, timeout=5))
        with pytest.raises(GoalCancelled) as caught:
            await first
        assert caught.value.preempted
        assert caught.value.target_id == 3
        await working(robot, 4)
        fake.step = 1000.0  # let goal 4 finish
        result = await second
    assert result.target_id == 4
    assert fake.received == [Goto(3), Goto(4)]  # the preempted goal sent no cancel


async def test_cancelling_a_preempted_goal_does_not_cancel_its_successor() -> None:
    async with connected(ScriptedRobot(**ENDLESS)) as (robot, fake):
        first = asyncio.create_task(robot.goto(3))
        await working(robot, 3)
        second = asyncio.create_task(robot.goto(4, timeout=5))
        await asyncio.sleep(0)  # the second goal starts and preempts the first
        first.cancel()
        with pytest.raises((asyncio.CancelledError, GoalCancelled)):
            await first
        await working(robot, 4)
        fake.step = 1000.0
        result = await second
        await flush(robot, fake)
    assert result.target_id == 4
    assert fake.of_type(Cancel) == []


async def test_goal_from_elsewhere_preempts() -> None:
    async with connected(ScriptedRobot(**ENDLESS)) as (robot, fake):
        task = asyncio.create_task(robot.goto(3))
        await working(robot, 3)
        fake.stop_motion()
        fake.set(target_num_id=-2, target_status=1)  # a task from the robot's HTTP API
        with pytest.raises(GoalCancelled) as caught:
            await task
    assert caught.value.preempted


async def test_cancelled_on_the_robot() -> None:
    async with connected(ScriptedRobot(**ENDLESS)) as (robot, fake):
        task = asyncio.create_task(robot.goto(3))
        await working(robot, 3)
        fake.stop_motion()
        fake.set(target_num_id=-1, target_status=0)  # firmware cancel: id -> -1
        with pytest.raises(GoalCancelled) as caught:
            await task
    assert not caught.value.preempted


async def test_navigation_stopped_under_the_goal() -> None:
    async with connected(ScriptedRobot(**ENDLESS)) as (robot, fake):
        task = asyncio.create_task(robot.goto(3))
        await working(robot, 3)
        fake.stop_motion()
        fake.set(nav_status=0, visual_status=-1)
        with pytest.raises(GoalCancelled, match="navigation"):
            await task


async def test_cancelling_the_awaiting_task_sends_cancel() -> None:
    async with connected(ScriptedRobot(**ENDLESS)) as (robot, fake):
        task = asyncio.create_task(robot.goto(3))
        await working(robot, 3)
        task.cancel()
        with pytest.raises(asyncio.CancelledError):
            await task
        await fake.command(Cancel)
        await robot.wait_until(lambda s: not s.goal_active, timeout=2)
    assert fake.received == [Goto(3), Cancel()]


async def test_anyio_fail_after_around_goto_stops_the_robot() -> None:
    async with connected(ScriptedRobot(**ENDLESS)) as (robot, fake):
        with pytest.raises(TimeoutError), anyio.fail_after(0.3):
            await robot.goto(3)
        await fake.command(Cancel)
        await robot.wait_until(lambda s: not s.goal_active, timeout=2)


async def test_overall_timeout_raises_and_cancels() -> None:
    async with connected(ScriptedRobot(**ENDLESS)) as (robot, fake):
        with pytest.raises(OperationTimeout) as caught:
            await robot.goto(3, timeout=0.3)
        await fake.command(Cancel)
    assert isinstance(caught.value, TimeoutError)
    assert isinstance(caught.value, GalileoTimeout)
    assert caught.value.status is not None


async def test_cancel_on_exit_false_sends_no_cancel() -> None:
    async with connected(ScriptedRobot(**ENDLESS)) as (robot, fake):
        task = asyncio.create_task(robot.goto(3, cancel_on_exit=False))
        await working(robot, 3)
        task.cancel()
        with pytest.raises(asyncio.CancelledError):
            await task
        await flush(robot, fake)
    assert fake.received == [Goto(3), Stop(100)]


async def test_cancel_on_exit_false_still_cancels_a_goal_never_accepted() -> None:
    fake = ScriptedRobot()
    fake.scripts[Goto] = ignore  # written, never shown accepted: it might start later
    async with connected(fake, accept_timeout=0.2) as (robot, _):
        with pytest.raises(AcceptTimeout):
            await robot.goto(3, timeout=5, cancel_on_exit=False)
        await fake.command(Cancel)
    assert fake.received[:2] == [Goto(3), Cancel()]


async def test_cancel_on_exit_false_cancels_a_goal_left_before_its_acceptance() -> None:
    fake = ScriptedRobot()
    fake.scripts[Goto] = ignore
    async with connected(fake) as (robot, _):
        task = asyncio.create_task(robot.goto(3, cancel_on_exit=False))
        await fake.command(Goto)
        task.cancel()
        with pytest.raises(asyncio.CancelledError):
            await task
        await fake.command(Cancel)
    assert fake.received[:2] == [Goto(3), Cancel()]


# --- busy, preconditions, arguments ------------------------------------------------------


async def test_goto_waits_while_busy() -> None:
    async with connected(ScriptedRobot(busy_status=1)) as (robot, fake):
        task = asyncio.create_task(robot.goto(3, timeout=5))
        await fake.frames(10)
        assert fake.received == []
        assert not task.done()
        fake.set(busy_status=0)
        result = await task
    assert result.target_id == 3
    assert fake.received == [Goto(3)]


async def test_busy_for_longer_than_the_timeout() -> None:
    async with connected(ScriptedRobot(busy_status=1)) as (robot, fake):
        with pytest.raises(OperationTimeout, match="busy"):
            await robot.goto(3, timeout=0.1)
        await nothing_was_sent_before_marker(robot, fake)  # stop is never held back


@pytest.mark.parametrize(
    ("fields", "words"),
    [
        ({"nav_status": 0, "visual_status": -1}, "navigation"),
        ({"visual_status": 0}, "visual"),
    ],
)
async def test_goto_preconditions(fields: dict[str, Any], words: str) -> None:
    async with connected(ScriptedRobot(**fields)) as (robot, fake):
        with pytest.raises(NotReady, match=words) as caught:
            await robot.goto(3)
        assert caught.value.status is not None
        assert caught.value.status.nav_status == fields.get("nav_status", 1)
        await nothing_was_sent_before_marker(robot, fake)


@pytest.mark.parametrize(
    ("args", "kwargs"),
    [
        ((256,), {}),
        ((-1,), {}),
        (("3",), {}),
        ((True,), {}),
        ((3.0,), {}),
        ((3,), {"timeout": -1}),
        ((3,), {"timeout": math.nan}),
        ((3,), {"accept_timeout": 0}),
    ],
)
async def test_goto_arguments_are_checked_before_sending(
    args: tuple[Any, ...], kwargs: dict[str, Any]
) -> None:
    async with connected() as (robot, fake):
        with pytest.raises(InvalidArgument) as caught:
            await robot.goto(*args, **kwargs)
        assert isinstance(caught.value, ValueError)
        await nothing_was_sent_before_marker(robot, fake)


# --- link failures -----------------------------------------------------------------------


async def test_unplug_mid_goal_fails_the_waiter_at_once() -> None:
    # stale_timeout is long: only the connection loss itself can end the wait in time.
    async with connected(ScriptedRobot(**ENDLESS), stale_timeout=5.0) as (robot, fake):
        task = asyncio.create_task(robot.goto(3))
        await working(robot, 3)
        fake.drop()
        with anyio.fail_after(0.5), pytest.raises(ConnectionLost):
            await task


async def test_unplug_with_reconnect_fails_the_goal_and_the_next_goal_works() -> None:
    options: dict[str, Any] = {"reconnect": True, "reconnect_initial": 0.02, "stale_timeout": 5.0}
    async with connected(ScriptedRobot(**ENDLESS), **options) as (robot, fake):
        task = asyncio.create_task(robot.goto(3))
        await working(robot, 3)
        events = robot.events()
        fake.drop()
        with anyio.fail_after(0.5), pytest.raises(ConnectionLost):
            await task
        with anyio.fail_after(2):
            async for event in events:
                if isinstance(event, ev.ConnectionRestored):  # frames again, after the reopen
                    break
        assert robot.link.reconnects == 1
        fake.step = 1000.0
        result = await robot.goto(4, timeout=5)
    assert result.target_id == 4
    assert fake.received == [Goto(3), Goto(4)]  # a lost link carries no cancel


async def test_silent_link_mid_goal_fails_the_waiter_once_the_link_is_given_up() -> None:
    # Stale is not an end (the link may recover): the goal fails when the link is given up
    # (stale_reconnect x stale_timeout, 1 s), and a lost link carries no cancel.
    async with connected(ScriptedRobot(**ENDLESS), stale_timeout=0.2) as (robot, fake):
        events = robot.events()
        task = asyncio.create_task(robot.goto(3))
        await working(robot, 3)
        fake.sending = False
        with anyio.fail_after(10.0):  # bounds only: a loaded machine may be slow
            async for event in events:
                if isinstance(event, ev.LinkStaleEvent):
                    break
        assert not task.done()
        with anyio.fail_after(10.0), pytest.raises(ConnectionLost):
            await task
        with pytest.raises(ConnectionLost, match="nothing was sent"):
            await robot.goto(3, timeout=1)
        with pytest.raises(ConnectionLost, match="nothing was sent"):
            await robot.forward(10)
    assert fake.received == [Goto(3)]
