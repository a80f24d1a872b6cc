"""Robot safety: nothing sent on a silent link, cancels that survive, bounded waits."""

from __future__ import annotations

import asyncio
from collections.abc import Awaitable, Callable
from typing import Any

import anyio
import pytest

import galileo_async as galileo
from galileo_async import (
    ConnectionLost,
    GalileoTimeout,
    InvalidArgument,
    LinkStale,
    NotReady,
    OperationTimeout,
    StopUnconfirmed,
)
from galileo_async import events as ev
from galileo_async import robot as robot_module
from galileo_async.protocol import AddTarget, Cancel, Goto, RawCommand, ResetTargets, Stop
from galileo_async.robot import Robot
from galileo_async.robot.operations import CANCEL_SEND_TIMEOUT
from tests.support.scripted_robot import ENDLESS, ScriptedRobot, connected, working

CLOSED: dict[str, Any] = {"nav_status": 0, "visual_status": -1}

# --- a silent (stale) or lost link: nothing is sent -------------------------------------

Call = Callable[[Robot], Awaitable[Any]]

SENDING_CALLS: list[tuple[str, Call]] = [
    ("goto", lambda r: r.goto(3, timeout=1)),
    ("goto_point", lambda r: r.goto_point(1.0, 2.0, timeout=1)),
    ("add_target", lambda r: r.add_target(1.0, 2.0)),
    ("reset_targets", lambda r: r.reset_targets()),
    ("start_patrol", lambda r: r.start_patrol(timeout=1)),
    ("stop_patrol", lambda r: r.stop_patrol(timeout=1)),
    ("set_patrol_dwell", lambda r: r.set_patrol_dwell(5)),
    ("start_navigation", lambda r: r.start_navigation(timeout=1)),
    ("stop_navigation", lambda r: r.stop_navigation(timeout=1)),
    ("start_mapping", lambda r: r.start_mapping(timeout=1)),
    ("stop_mapping", lambda r: r.stop_mapping(timeout=1)),
    ("save_map", lambda r: r.save_map()),
    ("update_map", lambda r: r.update_map()),
    ("start_charging", lambda r: r.start_charging(timeout=1)),
    ("stop_charging", lambda r: r.stop_charging(timeout=1)),
    ("save_dock", lambda r: r.save_dock()),
    ("rotate_to", lambda r: r.rotate_to(90, timeout=1)),
    ("pause", lambda r: r.pause(timeout=1)),
    ("resume", lambda r: r.resume(timeout=1)),
    ("forward", lambda r: r.forward(50)),
    ("backward", lambda r: r.backward(50)),
    ("turn_left", lambda r: r.turn_left(50)),
    ("turn_right", lambda r: r.turn_right(50)),
    ("send", lambda r: r.send(RawCommand(b"Z\x01"))),
    ("shutdown_host", lambda r: r.shutdown_host(confirm=True)),
]


async def _go_stale(robot: Robot, fake: ScriptedRobot) -> None:
    fake.sending = False
    with pytest.raises(LinkStale):
        await robot.wait_until(lambda s: False, timeout=2)
    assert robot.link.stale


async def test_every_operation_on_a_stale_link_raises_before_sending() -> None:
    async with connected(map_targets=5, stale_timeout=0.1) as (robot, fake):
        await _go_stale(robot, fake)
        for name, call in SENDING_CALLS:
            with pytest.raises(LinkStale, match="nothing was sent"):
                await call(robot)
            assert fake.received == [], name
        # stop() is still sent: the transmit side may work while the robot is silent; the
        # status cannot confirm it.
        with pytest.raises(StopUnconfirmed, match="stale") as info:
            await robot.stop()
        assert info.value.unconfirmed == ("goal", "patrol", "speed")
        await fake.command(Stop)
        await asyncio.sleep(0.05)  # room for a wrongly sent command to arrive after Stop
    assert fake.received == [Cancel(), Stop(100)]


async def test_cancel_on_a_stale_link_is_sent_then_reports_the_stale_link() -> None:
    async with connected(stale_timeout=0.1) as (robot, fake):
        await _go_stale(robot, fake)
        with pytest.raises(LinkStale, match="cancel: sent"):
            await robot.cancel(timeout=1)
        await fake.command(Cancel)
    assert fake.received == [Cancel()]


async def test_operations_work_again_once_frames_come_back() -> None:
    async with connected(stale_timeout=0.1) as (robot, fake):
        await _go_stale(robot, fake)
        with pytest.raises(LinkStale):
            await robot.start_patrol(timeout=1)
        fake.sending = True
        with anyio.fail_after(2):
            while robot.link.stale:
                await fake.frames(1)
        await robot.start_patrol(timeout=2)


async def test_operation_while_reconnecting_raises_connection_lost_before_sending() -> None:
    options: dict[str, Any] = {"reconnect": True, "reconnect_initial": 5.0, "stale_timeout": 5.0}
    async with connected(**options) as (robot, fake):
        fake.drop()
        with pytest.raises(ConnectionLost):
            await robot.wait_until(lambda s: False, timeout=2)
        with pytest.raises(ConnectionLost, match="nothing was sent"):
            await robot.goto(3, timeout=1)
        with pytest.raises(ConnectionLost, match="nothing was sent"):
            await robot.forward(10)
    assert fake.received == []


async def test_a_goal_goes_on_through_a_silent_spell_and_nothing_is_sent() -> None:
    # A stall the link recovers from is not an end: no cancel, and the goal arrives.
    async with connected(ScriptedRobot(**ENDLESS), stale_timeout=0.2) as (robot, fake):
        events = robot.events()
        task = asyncio.create_task(robot.goto(3))
        await working(robot, 3)
        fake.sending = False
        with anyio.fail_after(2.0):
            async for event in events:
                if isinstance(event, ev.LinkStaleEvent):
                    break
        fake.sending = True
        with anyio.fail_after(2.0):
            async for event in events:
                if isinstance(event, ev.LinkRestored):
                    break
        assert not task.done()
        fake.step = 1000.0  # the robot arrives
        with anyio.fail_after(2.0):
            result = await task
    assert result.target_id == 3
    assert fake.received == [Goto(3)]


# --- the exit cancel survives a native double cancel ------------------------------------


async def test_double_cancel_of_the_goal_task_still_sends_cancel() -> None:
    async with connected(ScriptedRobot(**ENDLESS)) as (robot, fake):
        task = asyncio.create_task(robot.goto(3))
        await working(robot, 3)
        task.cancel()
        await asyncio.sleep(0)
        task.cancel()
        with pytest.raises(asyncio.CancelledError):
            await task
        await fake.command(Cancel)
        await robot.wait_until(lambda s: not s.goal_active, timeout=2)
    assert fake.received == [Goto(3), Cancel()]


def _cancel_senders() -> list[asyncio.Task[Any]]:
    return [
        t
        for t in asyncio.all_tasks()
        if not t.done() and "Operations" in t.get_coro().__qualname__  # type: ignore[union-attr]
    ]


async def test_close_ends_a_cancel_still_waiting_to_be_written() -> None:
    # Command pacing of 5 s: the exit cancel waits in the link's queue when close() comes.
    async with connected(ScriptedRobot(**ENDLESS), min_command_interval=5.0) as (robot, fake):
        task = asyncio.create_task(robot.goto(3))
        await working(robot, 3)
        task.cancel()
        await asyncio.sleep(0)
        task.cancel()
        with pytest.raises(asyncio.CancelledError):
            await task
        assert len(_cancel_senders()) == 1  # the cancel outlived the goal's task
        # close() gives it CANCEL_SEND_TIMEOUT to be written (a stop under way is written in
        # full), then closes the link all the same: bounded.
        with anyio.fail_after(CANCEL_SEND_TIMEOUT + 1.0):
            await robot.close()
        assert _cancel_senders() == []  # ... but not close()
    assert fake.received == [Goto(3)]


# --- dynamic targets across a reconnect -------------------------------------------------


async def test_add_target_after_a_reconnect_needs_a_new_reset() -> None:
    options: dict[str, Any] = {"reconnect": True, "reconnect_initial": 0.02, "stale_timeout": 5.0}
    async with connected(ScriptedRobot(map_targets=7), map_targets=7, **options) as (robot, fake):
        await robot.reset_targets()
        assert await robot.add_target(1.0, 1.0) == 7
        await fake.command(AddTarget)
        events = robot.events()
        fake.drop()
        fake.dynamic_targets = 0  # the robot rebooted: its dynamic targets are gone
        with anyio.fail_after(2):
            async for event in events:
                if isinstance(event, ev.ConnectionRestored):  # frames again, after the reopen
                    break
        assert robot.link.reconnects == 1
        await robot.wait_until(lambda s: True, timeout=2)
        with pytest.raises(NotReady, match=r"reconnected.*reset_targets\(\)"):
            await robot.add_target(2.0, 2.0)
        await robot.reset_targets()
        assert await robot.add_target(3.0, 3.0) == 7
        result = await robot.goto_point(0.5, 0.5, timeout=5)
        assert result.target_id == 7
        await fake.command(Goto)
    assert fake.received[:4] == [
        ResetTargets(),
        AddTarget(1.0, 1.0),
        ResetTargets(),
        AddTarget(3.0, 3.0),
    ]


# --- finite default timeouts --------------------------------------------------------------


async def test_default_timeouts_are_finite() -> None:
    goal_default = getattr(robot_module, "DEFAULT_GOAL_TIMEOUT", None)
    wait_default = getattr(robot_module, "DEFAULT_WAIT_TIMEOUT", None)
    assert goal_default == 600.0
    assert isinstance(wait_default, float)
    assert 0 < wait_default < goal_default
    async with connected() as (robot, _):
        assert getattr(robot, "goal_timeout", None) == goal_default
        assert getattr(robot, "wait_timeout", None) == wait_default


async def test_goto_without_a_timeout_uses_the_goal_timeout() -> None:
    async with connected(ScriptedRobot(**ENDLESS), goal_timeout=0.3) as (robot, fake):
        with anyio.fail_after(3), pytest.raises(OperationTimeout, match=r"within 0\.3 s"):
            await robot.goto(3)
        await fake.command(Cancel)


async def test_goto_point_without_a_timeout_uses_the_goal_timeout() -> None:
    fake = ScriptedRobot(map_targets=5, **ENDLESS)
    async with connected(fake, map_targets=5, goal_timeout=0.3) as (robot, _):
        with anyio.fail_after(3), pytest.raises(OperationTimeout, match=r"within 0\.3 s"):
            await robot.goto_point(1.0, 1.0)
        await fake.command(Cancel)


async def test_goto_with_timeout_none_has_no_limit() -> None:
    # 50 frames of at least 5 ms each to arrive: far beyond the goal_timeout of 0.1 s.
    fake = ScriptedRobot(start_distance=1.0, step=0.02)
    async with connected(fake, goal_timeout=0.1) as (robot, _):
        with anyio.fail_after(10):
            result = await robot.goto(3, timeout=None)
    assert result.elapsed > 0.1


async def test_wait_until_without_a_timeout_uses_the_wait_timeout() -> None:
    async with connected(wait_timeout=0.1) as (robot, _):
        with anyio.fail_after(3), pytest.raises(GalileoTimeout, match=r"0\.1 s"):
            await robot.wait_until(lambda s: False)
        assert robot.status is not None
        assert robot.status.time_stamp is not None
        later = robot.status.time_stamp + 40  # at least 0.2 s away
        with anyio.fail_after(10):
            await robot.wait_until(lambda s: (s.time_stamp or 0) >= later, timeout=None)


async def test_bad_default_timeouts_are_rejected() -> None:
    fake = await ScriptedRobot().start()
    try:
        for bad in ({"goal_timeout": 0}, {"wait_timeout": -1}, {"goal_timeout": "1"}):
            with pytest.raises(InvalidArgument):
                await galileo.connect(fake.url, reconnect=False, **bad)
    finally:
        await fake.close()


# --- messages -----------------------------------------------------------------------------


async def test_missing_map_targets_names_every_way_to_set_it() -> None:
    async with connected() as (robot, _):
        with pytest.raises(NotReady, match="--map-targets N or GALILEO_MAP_TARGETS"):
            await robot.add_target(1.0, 1.0)
