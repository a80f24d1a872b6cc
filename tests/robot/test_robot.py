"""Robot operations other than goto, and connect()/close(), against the scripted fake robot."""

from __future__ import annotations

import asyncio
import math
import time
from typing import Any

import anyio
import pytest

import galileo_async as galileo
from galileo_async import (
    ConnectionLost,
    GalileoConnectionError,
    GoalCancelled,
    InvalidArgument,
    NotReady,
    OperationFailed,
    OperationTimeout,
    TargetStatus,
    UnconfirmedOperation,
)
from galileo_async.events import Event, NavigationOpened
from galileo_async.protocol import (
    AddTarget,
    Backward,
    Cancel,
    Forward,
    Goto,
    Pause,
    RawCommand,
    ResetTargets,
    Resume,
    RotateTo,
    ShutdownHost,
    StartNavigation,
    Stop,
    StopNavigation,
    TurnLeft,
    TurnRight,
    encode,
)
from galileo_async.transports import LinkStats
from tests.support.scripted_robot import (
    ENDLESS,
    FAST_OPTIONS,
    REACTION_FRAMES,
    ScriptedRobot,
    connected,
    flush,
    ignore,
    nothing_was_sent_before_marker,
    working,
)

CLOSED: dict[str, Any] = {"nav_status": 0, "visual_status": -1}

# --- connect and close ----------------------------------------------------------------


async def test_connect_is_awaitable_and_close_is_idempotent() -> None:
    fake = await ScriptedRobot().start()
    try:
        robot = await galileo.connect(fake.url, **FAST_OPTIONS)
        assert robot.status is not None  # connect waited for the first frame
        assert isinstance(robot.link, LinkStats)
        assert robot.link.frames >= 1
        started = time.monotonic()
        await asyncio.gather(robot.close(), robot.close())
        await robot.close()
        assert time.monotonic() - started < 2.0
        assert robot.closed
        with pytest.raises(GalileoConnectionError):
            await robot.goto(3)
        with pytest.raises(GalileoConnectionError):
            await robot.stop()
    finally:
        await fake.close()


async def test_close_fails_a_running_goal_at_once() -> None:
    async with connected(ScriptedRobot(**ENDLESS)) as (robot, _):
        task = asyncio.create_task(robot.goto(3))
        await working(robot, 3)
        await robot.close()
        with anyio.fail_after(0.5), pytest.raises(ConnectionLost):
            await task


async def test_connect_without_frames_fails_and_leaves_nothing_behind() -> None:
    fake = ScriptedRobot()
    fake.sending = False
    await fake.start()
    try:
        with pytest.raises(GalileoConnectionError):
            await galileo.connect(fake.url, **(FAST_OPTIONS | {"first_status_timeout": 0.2}))
    finally:
        await fake.close()


async def test_connect_rejects_bad_robot_options() -> None:
    fake = await ScriptedRobot().start()
    try:
        for bad in ({"map_targets": 300}, {"arrive_tolerance": -1}, {"accept_timeout": 0}):
            with pytest.raises(InvalidArgument):
                await galileo.connect(fake.url, **(FAST_OPTIONS | bad))
    finally:
        await fake.close()


async def test_statuses_events_and_wait_until() -> None:
    async with connected(ScriptedRobot(**CLOSED)) as (robot, _):
        statuses = robot.statuses()
        first = await anext(statuses)
        assert first.nav_status == 0
        following = await statuses.next(timeout=2)  # the stream's coroutine, with a timeout
        assert following.time_stamp != first.time_stamp
        events = robot.events()
        await robot.start_navigation(timeout=2)
        seen: list[Event] = []
        with anyio.fail_after(2):
            async for event in events:
                seen.append(event)
                if isinstance(event, NavigationOpened):
                    break
        with pytest.raises(InvalidArgument):
            await robot.wait_until(lambda s: True, timeout=-1)


# --- navigation -----------------------------------------------------------------------


async def test_start_navigation_waits_for_navigation_and_visual() -> None:
    async with connected(ScriptedRobot(**CLOSED)) as (robot, fake):
        await robot.start_navigation(timeout=2)
        assert robot.status is not None
        assert robot.status.navigating
        assert robot.status.visual_initialised
        assert fake.received == [StartNavigation()]


async def test_start_navigation_when_already_navigating_sends_nothing() -> None:
    async with connected() as (robot, fake):
        await robot.start_navigation(timeout=2)
        await nothing_was_sent_before_marker(robot, fake)


async def test_start_navigation_while_mapping_is_not_ready() -> None:
    async with connected(ScriptedRobot(map_status=1, **CLOSED)) as (robot, fake):
        with pytest.raises(NotReady, match="map") as caught:
            await robot.start_navigation()
        assert caught.value.status is not None
        assert caught.value.status.mapping
        await nothing_was_sent_before_marker(robot, fake)


async def test_start_navigation_ignored_by_the_firmware() -> None:
    fake = ScriptedRobot(**CLOSED)
    fake.scripts[StartNavigation] = ignore
    async with connected(fake) as (robot, _):
        with pytest.raises(UnconfirmedOperation, match="ignores a start"):
            await robot.start_navigation(timeout=0.2)


async def test_start_navigation_visual_never_initialises() -> None:
    async def opens_blind(fake: ScriptedRobot, command: Any) -> None:
        await fake.frames(REACTION_FRAMES)
        fake.set(nav_status=1, visual_status=0)

    fake = ScriptedRobot(**CLOSED)
    fake.scripts[StartNavigation] = opens_blind
    async with connected(fake) as (robot, _):
        with pytest.raises(UnconfirmedOperation, match="visual"):
            await robot.start_navigation(timeout=0.3)


async def test_stop_navigation_waits_until_closed() -> None:
    async with connected() as (robot, fake):
        await robot.stop_navigation(timeout=2)
        assert robot.status is not None
        assert not robot.status.navigating
        assert fake.received == [StopNavigation()]
        await robot.stop_navigation(timeout=2)  # already closed: nothing to do
        assert fake.received == [StopNavigation()]


# --- goto_point and dynamic targets ----------------------------------------------------


async def test_goto_point_sends_reset_add_goto() -> None:
    fake = ScriptedRobot(map_targets=5)
    async with connected(fake, map_targets=5) as (robot, _):
        result = await robot.goto_point(1.5, -2.0, timeout=5)
        again = await robot.goto_point(0.5, 0.25, timeout=5)
    assert result.target_id == 5
    assert again.target_id == 5  # reset each time: the count starts over
    assert [encode(c) for c in fake.received[:3]] == [
        bytes.fromhex("cdebd7 03 677200"),
        bytes.fromhex("cdebd7 0a 6769 0000c03f 000000c0"),
        bytes.fromhex("cdebd7 02 6705"),
    ]
    assert fake.received[3:] == [ResetTargets(), AddTarget(0.5, 0.25), Goto(5)]


async def test_goto_point_without_map_targets_is_not_ready() -> None:
    async with connected() as (robot, fake):
        with pytest.raises(NotReady, match="map_targets"):
            await robot.goto_point(1.0, 2.0)
        await nothing_was_sent_before_marker(robot, fake)


async def test_goto_point_checks_coordinates_before_sending() -> None:
    async with connected(map_targets=5) as (robot, fake):
        with pytest.raises(InvalidArgument):
            await robot.goto_point(math.inf, 0.0)
        await nothing_was_sent_before_marker(robot, fake)


async def test_add_target_counts_ids_after_a_reset() -> None:
    async with connected(map_targets=7) as (robot, fake):
        with pytest.raises(NotReady, match="reset_targets"):
            await robot.add_target(1.0, 1.0)
        await robot.reset_targets()
        assert await robot.add_target(1.0, 1.0) == 7
        assert await robot.add_target(2.0, 2.0) == 8
        await robot.reset_targets()
        assert await robot.add_target(3.0, 3.0) == 7
        await flush(robot, fake)
    assert fake.received[:-1] == [
        ResetTargets(),
        AddTarget(1.0, 1.0),
        AddTarget(2.0, 2.0),
        ResetTargets(),
        AddTarget(3.0, 3.0),
    ]


# --- goal control ---------------------------------------------------------------------


async def test_pause_resume_cancel_a_running_goal() -> None:
    async with connected(ScriptedRobot(**ENDLESS)) as (robot, fake):
        goal = asyncio.create_task(robot.goto(3))
        await working(robot, 3)
        await robot.pause(timeout=2)
        paused = robot.status
        assert paused is not None
        assert paused.target_status == TargetStatus.PAUSED
        assert not goal.done()  # paused is not an end
        await robot.resume(timeout=2)
        resumed = robot.status
        assert resumed is not None
        assert resumed.target_status == TargetStatus.WORKING
        await robot.cancel(timeout=2)
        with pytest.raises(GoalCancelled):
            await goal
    assert fake.received[1:] == [Pause(), Resume(), Cancel()]


async def test_pause_and_resume_need_the_right_goal_state() -> None:
    async with connected() as (robot, fake):
        with pytest.raises(NotReady, match="working"):
            await robot.pause()
        with pytest.raises(NotReady, match="paused"):
            await robot.resume()
        await nothing_was_sent_before_marker(robot, fake)


async def test_cancel_without_a_goal_still_sends_and_returns() -> None:
    async with connected(ScriptedRobot(busy_status=1)) as (robot, fake):
        await robot.cancel(timeout=1)  # never held back by busy_status
        await fake.command(Cancel)


# --- rotate_to ------------------------------------------------------------------------


async def test_rotate_to_times_out_saying_the_firmware_may_ignore_it() -> None:
    async with connected() as (robot, fake):
        with pytest.raises(UnconfirmedOperation, match="ignore the rotate command 'a'"):
            await robot.rotate_to(-90, timeout=0.2)
    assert fake.received == [RotateTo(-90)]
    assert encode(fake.received[0]) == bytes.fromhex("cdebd7 03 61 01 5a")


async def test_rotate_to_waits_for_a_new_done_not_the_stale_one() -> None:
    marks: dict[str, int] = {}

    async def rotates(fake: ScriptedRobot, command: Any) -> None:
        await fake.frames(4)  # stale frames still show angle_goal_status 1
        fake.set(angle_goal_status=0)
        await fake.frames(4)
        marks["done_from"] = fake.frames_sent + 1
        fake.set(angle_goal_status=1)

    fake = ScriptedRobot(angle_goal_status=1)
    fake.scripts[RotateTo] = rotates
    async with connected(fake) as (robot, _):
        await robot.rotate_to(45.4, timeout=2)
        assert robot.status is not None
        assert robot.status.time_stamp is not None
        assert robot.status.time_stamp >= marks["done_from"]
    assert fake.received == [RotateTo(45)]


async def test_rotate_to_reports_an_error() -> None:
    async def fails(fake: ScriptedRobot, command: Any) -> None:
        await fake.frames(REACTION_FRAMES)
        fake.set(angle_goal_status=2)

    fake = ScriptedRobot()
    fake.scripts[RotateTo] = fails
    async with connected(fake) as (robot, _):
        with pytest.raises(OperationFailed):
            await robot.rotate_to(10, timeout=2)


async def test_rotate_to_checks_arguments_and_preconditions() -> None:
    async with connected(ScriptedRobot(target_num_id=1, target_status=1)) as (robot, fake):
        for bad in (181, -181, float("nan"), "90", True):
            with pytest.raises(InvalidArgument):
                await robot.rotate_to(bad)  # type: ignore[arg-type]
        with pytest.raises(NotReady, match="no goal"):
            await robot.rotate_to(90)
        await nothing_was_sent_before_marker(robot, fake)


# --- teleoperation and raw commands ---------------------------------------------------


async def test_teleop_commands() -> None:
    async with connected() as (robot, fake):
        await robot.forward(50)
        await robot.backward(20)
        await robot.turn_left(10)
        await robot.turn_right(100)
        await robot.zero_speed(30)
        with anyio.fail_after(2):
            while len(fake.received) < 5:
                await fake.frames(1)
    assert fake.received == [Forward(50), Backward(20), TurnLeft(10), TurnRight(100), Stop(30)]


async def test_teleop_arguments_are_checked_before_sending() -> None:
    async with connected() as (robot, fake):
        for call in (robot.forward, robot.backward, robot.turn_left, robot.turn_right):
            with pytest.raises(InvalidArgument):
                await call(101)
        for stop in (robot.stop, robot.zero_speed):
            with pytest.raises(InvalidArgument):
                await stop(-1)
        with pytest.raises(InvalidArgument):
            await robot.stop(timeout=-1)
        await nothing_was_sent_before_marker(robot, fake)


async def test_send_any_command_object() -> None:
    async with connected() as (robot, fake):
        with pytest.raises(InvalidArgument):
            await robot.send(b"\x48\x00")  # type: ignore[arg-type]
        await robot.send(RawCommand(b"Z\x01"))
        await flush(robot, fake)
    assert fake.received == [RawCommand(b"Z\x01"), Stop(100)]


async def test_commands_wait_while_busy() -> None:
    async with connected(ScriptedRobot(busy_status=1)) as (robot, fake):
        task = asyncio.create_task(robot.forward(40, timeout=5))
        await fake.frames(10)
        assert not task.done()
        fake.set(busy_status=0)
        await task
        with anyio.fail_after(2):
            await fake.command(Forward)
        fake.set(busy_status=1)
        await robot.wait_until(lambda s: s.is_busy, timeout=2)
        with pytest.raises(OperationTimeout, match="busy"):
            await robot.start_patrol(timeout=0.1)
        await flush(robot, fake)
    assert fake.received == [Forward(40), Stop(100)]


async def test_shutdown_host_needs_confirm() -> None:
    async with connected() as (robot, fake):
        with pytest.raises(InvalidArgument, match="confirm=True"):
            await robot.shutdown_host()
        with pytest.raises(InvalidArgument):
            await robot.shutdown_host(confirm="yes")  # type: ignore[arg-type]
        await nothing_was_sent_before_marker(robot, fake)
        await robot.shutdown_host(confirm=True)
        await fake.command(ShutdownHost)


async def test_sim_url_knows_its_map_targets() -> None:
    import galileo_async as galileo

    async with galileo.connect("sim://?speed=20&targets=0,0;1,0;2,0") as robot:
        assert robot.map_targets == 3
    async with galileo.connect("sim://?speed=20", map_targets=9) as robot:
        assert robot.map_targets == 9
