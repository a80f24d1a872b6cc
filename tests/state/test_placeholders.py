"""Placeholder frames of the vendor's serial node are not the robot's state (#14 item 15).

The node sends its constructor's defaults (power 0 V, target and angle status -1, pose 0,
navigation and visual 0) until the navigation system's first status reaches it, and again
after it restarts. The scripted robot sends exactly those (scripted_robot.DEFAULTS).
"""

from __future__ import annotations

import asyncio
import json
import os
import sys
from collections.abc import Callable

import anyio
import pytest

from galileo_async.cli import ExitCode
from galileo_async.errors import NotReady, StopUnconfirmed, UnconfirmedOperation
from galileo_async.events import Event, NavigationOpened
from galileo_async.models import GalileoStatus
from galileo_async.protocol import V2_DEFAULTS, Cancel, Stop, StopPatrol
from galileo_async.state import StatusStore
from tests.support.scripted_robot import (
    DEFAULTS,
    READY,
    ScriptedRobot,
    connected,
    nothing_was_sent_before_marker,
)

STEP = 2.0  # upper bound for anything that should happen promptly


def placeholder(time_stamp: int) -> GalileoStatus:
    return GalileoStatus(**{**V2_DEFAULTS, "time_stamp": time_stamp})


async def frames_until(fake: ScriptedRobot, condition: Callable[[], bool]) -> None:
    """Wait frame by frame of the fake until ``condition`` holds (bounded)."""
    with anyio.fail_after(STEP):
        while not condition():
            await fake.frames(1)


def test_placeholder_is_recognised_and_a_real_status_is_not() -> None:
    assert placeholder(1).is_placeholder
    assert GalileoStatus(**DEFAULTS).is_placeholder
    # Any field of the robot's own makes it a real status: the voltage, a pose, navigation.
    for field, value in (("power", 24.0), ("current_pose_x", 0.5), ("nav_status", 1)):
        assert not GalileoStatus(**{**V2_DEFAULTS, field: value}).is_placeholder, field


async def test_store_keeps_placeholders_out_of_status_waiters_and_events() -> None:
    store = StatusStore()
    events = store.events()
    real = GalileoStatus(**{**V2_DEFAULTS, **READY})
    store.update(placeholder(1))
    assert store.status is None
    assert store.awaiting_robot
    assert store.updates == 0
    store.update(real)
    assert store.status == real
    assert not store.awaiting_robot
    store.update(placeholder(1))  # the node restarted
    assert store.status is None
    assert store.awaiting_robot
    # Nothing is derived from the placeholder (no NavigationClosed, VisualLost …), and the
    # first real status after it is a new start, not a transition from the placeholder.
    store.update(real)
    store.close()
    assert [event async for event in events] == []


async def test_connect_during_placeholders_then_the_robot_reports() -> None:
    fake = ScriptedRobot(**DEFAULTS)
    async with connected(fake) as (robot, fake):
        await frames_until(fake, lambda: robot.link.frames >= 3)
        assert robot.status is None
        assert robot.awaiting_robot
        assert robot.link.stale is False  # the link is up
        fake.set(**READY)
        status = await robot.wait_until(lambda _s: True, timeout=STEP)
        assert status.power == 24.0
        assert status.navigating
        assert not robot.awaiting_robot


async def test_node_restart_clears_the_status_and_derives_no_event() -> None:
    async with connected() as (robot, fake):
        events: list[Event] = []

        async def collect() -> None:
            async for event in robot.events():
                events.append(event)

        async with anyio.create_task_group() as group:
            group.start_soon(collect)
            await asyncio.sleep(0)
            fake.set(**DEFAULTS)
            await frames_until(fake, lambda: robot.status is None)
            assert robot.awaiting_robot
            frames = robot.link.frames
            await frames_until(fake, lambda: robot.link.frames >= frames + 3)
            assert robot.status is None
            fake.set(**{**READY, "nav_status": 0})
            await robot.wait_until(lambda s: s.nav_status == 0, timeout=STEP)
            fake.set(nav_status=1)  # a real transition after the restart is reported
            await robot.wait_until(lambda s: s.navigating, timeout=STEP)
            await frames_until(fake, lambda: bool(events))
            group.cancel_scope.cancel()
        assert [type(event) for event in events] == [NavigationOpened]


@pytest.mark.parametrize("power", [0.0, 12.5])
async def test_placeholder_shape_with_a_voltage_is_a_status(power: float) -> None:
    fake = ScriptedRobot(**{**DEFAULTS, "power": power})
    async with connected(fake) as (robot, fake):
        await frames_until(fake, lambda: robot.link.frames >= 3)
        assert (robot.status is None) is (power == 0.0)


async def test_goto_after_a_node_restart_waits_for_the_robot_then_drives() -> None:
    async with connected() as (robot, fake):
        fake.set(**DEFAULTS)  # the serial node restarted; navigation is still open
        await frames_until(fake, lambda: robot.status is None)
        going = asyncio.ensure_future(robot.goto(1, timeout=STEP))
        frames = robot.link.frames
        await frames_until(fake, lambda: robot.link.frames >= frames + 3)
        assert not going.done()
        assert fake.received == []  # nothing is sent on a placeholder's word
        fake.set(**READY)
        result = await going
        assert result.target_id == 1
        assert [type(command).__name__ for command in fake.received] == ["Goto"]


async def test_an_operation_gives_up_within_its_own_timeout_and_sends_nothing() -> None:
    async with connected(ScriptedRobot(**DEFAULTS)) as (robot, fake):
        with pytest.raises(NotReady, match=r"has not reported within 0\.3 s") as caught:
            await robot.start_patrol(timeout=0.3)
        assert "placeholder" in str(caught.value)
        assert caught.value.status is None
        await nothing_was_sent_before_marker(robot, fake)


@pytest.mark.parametrize("route", ["task.cancel()", "anyio.move_on_after"])
async def test_waiting_for_the_robot_can_be_cancelled(route: str) -> None:
    async with connected(ScriptedRobot(**DEFAULTS)) as (robot, fake):
        if route == "task.cancel()":
            going = asyncio.ensure_future(robot.goto(1, timeout=STEP))
            await fake.frames(2)
            going.cancel()
            with pytest.raises(asyncio.CancelledError):
                await going
        else:
            with anyio.move_on_after(0.1) as scope:
                await robot.goto(1, timeout=STEP)
            assert scope.cancelled_caught
        await nothing_was_sent_before_marker(robot, fake)


async def run_galileo(url: str, *args: str) -> tuple[int, str, str]:
    """Run the galileo command against ``url``; its exit code, stdout and stderr."""
    process = await asyncio.create_subprocess_exec(
        sys.executable, "-m", "galileo_async", "-p", url, *args,
        stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE,
        env={**os.environ, "COLUMNS": "200", "NO_COLOR": "1"},
    )  # fmt: skip
    try:
        out, err = await asyncio.wait_for(process.communicate(), 60)
    finally:
        if process.returncode is None:
            process.kill()
            await process.wait()
    assert process.returncode is not None
    return process.returncode, out.decode(), err.decode()


async def test_cli_status_says_the_navigation_system_has_not_reported() -> None:
    fake = await ScriptedRobot(**DEFAULTS).start()
    try:
        code, _out, err = await run_galileo(fake.url, "status")
    finally:
        await fake.close()
    assert code == ExitCode.NOT_READY, err
    assert "navigation system has not reported yet" in err
    assert "nav start" not in err  # not the hint for a closed navigation


async def test_cli_status_waits_for_the_first_report() -> None:
    fake = await ScriptedRobot(**DEFAULTS).start()

    async def report_later() -> None:
        await fake.frames(20)  # placeholders to the connected command first, however late
        fake.set(**READY)

    report = asyncio.create_task(report_later())
    try:
        code, out, err = await run_galileo(fake.url, "status", "--json")
    finally:
        report.cancel()
        await asyncio.gather(report, return_exceptions=True)
        await fake.close()
    assert code == 0, err
    assert "waiting for the navigation system" in err
    assert json.loads(out)["status"]["power"] == 24.0


async def test_cancel_and_stop_on_placeholders_say_the_robot_has_not_reported() -> None:
    async with connected(ScriptedRobot(**DEFAULTS)) as (robot, fake):
        assert robot.awaiting_robot
        with pytest.raises(UnconfirmedOperation) as cancelled:
            await robot.cancel(timeout=0.2)
        assert "only placeholder frames" in str(cancelled.value)
        assert "still active" not in str(cancelled.value)
        with pytest.raises(StopUnconfirmed) as stopped:
            await robot.stop(timeout=0.2)
        assert "only placeholder frames" in str(stopped.value)
        assert stopped.value.unconfirmed == ("goal", "patrol", "speed")
        await fake.command(Stop)
    assert fake.received == [Cancel(), StopPatrol(), Cancel(), Stop(100)]
