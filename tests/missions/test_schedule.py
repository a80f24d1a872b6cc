"""run_schedule on the virtual clock: windows, charging pauses, closing, overlaps, DST."""

from __future__ import annotations

import asyncio
from datetime import datetime, timedelta, timezone
from typing import Any
from zoneinfo import ZoneInfo

import anyio
import pytest

from galileo_async import ChargeStatus, Robot
from galileo_async.missions.schedule import (
    ChargingPause,
    Excluded,
    Resumed,
    WindowClosed,
    WindowOpened,
    WindowSkipped,
    run_schedule,
)
from galileo_async.missions.schedule_model import Schedule
from galileo_async.protocol import StartCharging, Stop
from galileo_async.testing import SimulatedDevice, simulated_robot
from tests.support.fake_runner import FakeRuns, StepEnded, fake_runner

BERLIN = ZoneInfo("Europe/Berlin")
#: A Monday.
MONDAY = datetime(2026, 3, 23, tzinfo=BERLIN)

PATROL = {
    "mission": "patrol",
    "steps": [{"loop": {"steps": [{"goto": 1}, {"dwell": 30}, {"goto": 2}, {"dwell": 30}]}}],
}
IDLE = {"mission": "idle", "steps": [{"loop": {"steps": [{"dwell": 60}]}}]}


def schedule(**fields: Any) -> Schedule:
    return Schedule.model_validate({"time_zone": "Europe/Berlin", **fields})


class Played:
    """run_schedule in a task, its events with their wall times, the runner's calls."""

    def __init__(self) -> None:
        self.events: list[object] = []
        self.runs = FakeRuns([])

    def of(self, kind: type[Any]) -> list[Any]:
        return [event for event in self.events if isinstance(event, kind)]


async def play(
    robot: Robot, plan: Schedule, start: datetime, seconds: float, device: SimulatedDevice
) -> Played:
    played = Played()
    task = asyncio.ensure_future(
        run_schedule(
            robot, plan, now=start, on_progress=played.events.append,
            runner=fake_runner(played.runs),
        )
    )  # fmt: skip
    await device.advance(seconds)
    task.cancel()
    with pytest.raises(asyncio.CancelledError):
        await task
    return played


def local(event: Any) -> tuple[int, int]:
    """An event's wall time as (hour, minute) in Berlin."""
    at = event.at.astimezone(BERLIN)
    return at.hour, at.minute


async def test_a_working_day_with_a_lunch_break_and_charging() -> None:
    plan = schedule(
        windows=[
            {"days": "weekdays", "start": "08:00", "stop": "12:00", "mission": PATROL,
             "stop_pose": 0},
            {"days": "weekdays", "start": "13:00", "stop": "18:00", "mission": PATROL,
             "stop_pose": "dock"},
        ],
        battery={"go_charge_below_percent": 20, "resume_at_percent": 80},
    )  # fmt: skip
    async with simulated_robot() as (robot, device):
        start = MONDAY.replace(hour=7, minute=50)
        played = await play(robot, plan, start, 10.25 * 3600, device)
        status = robot.status
    opened, closed = played.of(WindowOpened), played.of(WindowClosed)
    assert [local(event) for event in opened] == [(8, 0), (13, 0)]
    assert [event.reason for event in closed] == ["window closed", "window closed"]
    assert [local(event)[0] for event in closed] == [12, 18]
    pauses, resumed = played.of(ChargingPause), played.of(Resumed)
    assert pauses
    assert all(pause.reason == "battery low" for pause in pauses)
    assert len(resumed) >= len(pauses) - 1
    # Each pause resumes the mission where it stopped: the runner is called with resume.
    # (a pause when a window opens comes before its first run: that run starts afresh)
    calls = played.runs.calls
    assert [resume for _, resume, _ in calls].count(False) == 2
    assert all(first > 0 for _, resume, first in calls if resume)
    assert status is not None
    assert status.charge_status != ChargeStatus.FREE  # the dock at 18:00


async def test_docking_from_outside_pauses_the_mission_until_charged() -> None:
    plan = schedule(
        windows=[{"days": "every day", "start": "08:00", "stop": "09:00", "mission": PATROL}]
    )
    async with simulated_robot() as (robot, device):
        played = Played()
        task = asyncio.ensure_future(
            run_schedule(robot, plan, now=MONDAY.replace(hour=8), on_progress=played.events.append,
                         runner=fake_runner(played.runs))
        )  # fmt: skip
        await device.advance(100)
        await robot.send(StartCharging())  # someone docks it
        await device.advance(600)
        task.cancel()
        with pytest.raises(asyncio.CancelledError):
            await task
    assert [pause.reason for pause in played.of(ChargingPause)] == ["docked"]
    assert len(played.of(Resumed)) == 1
    assert [call[1] for call in played.runs.calls] == [False, True]


@pytest.mark.parametrize(
    ("policy", "closes_after_stop"), [("finish_step", True), ("stop_now", False)]
)
async def test_window_close_finishes_the_step_or_stops_now(
    policy: str, closes_after_stop: bool
) -> None:
    long_dwell = {"mission": "wait", "steps": [{"dwell": 10}, {"dwell": 350}, {"dwell": 10}]}
    plan = schedule(
        windows=[
            {"days": "every day", "start": "08:00", "stop": "08:05", "mission": long_dwell,
             "stop_pose": 3}
        ],
        on_window_close=policy,
    )  # fmt: skip
    async with simulated_robot() as (robot, device):
        played = await play(robot, plan, MONDAY.replace(hour=8), 1200, device)
        status = robot.status
    [closed] = played.of(WindowClosed)
    stop = MONDAY.replace(hour=8, minute=5)
    # steps[1] ends at 08:06:00; the stop pose is a few seconds away
    assert (closed.at > stop + timedelta(seconds=60)) is closes_after_stop
    assert closed.at < stop + timedelta(seconds=90)
    ended = [event for event in played.events if isinstance(event, StepEnded)]
    assert [event.path for event in ended] == (
        ["steps[0]", "steps[1]"] if closes_after_stop else ["steps[0]"]
    )
    assert status is not None
    assert status.target_num_id == 3  # the stop pose


@pytest.mark.parametrize("policy", ["wait", "preempt", "skip"])
async def test_overlapping_windows(policy: str) -> None:
    plan = schedule(
        windows=[
            {"days": "every day", "start": "08:00", "stop": "09:00", "mission": IDLE, "name": "a"},
            {"days": "every day", "start": "08:30", "stop": "09:30", "mission": IDLE, "name": "b",
             "on_overlap": policy},
        ],
        on_window_close="stop_now",
    )  # fmt: skip
    async with simulated_robot() as (robot, device):
        played = await play(robot, plan, MONDAY.replace(hour=7, minute=59), 2 * 3600, device)
    opened = [(event.name, local(event)) for event in played.of(WindowOpened)]
    closed = [(event.name, local(event), event.reason) for event in played.of(WindowClosed)]
    if policy == "wait":
        assert opened == [("a", (8, 0)), ("b", (9, 0))]
        assert closed == [("a", (9, 0), "window closed"), ("b", (9, 30), "window closed")]
    elif policy == "preempt":
        assert opened == [("a", (8, 0)), ("b", (8, 30))]
        assert closed == [("a", (8, 30), "preempted"), ("b", (9, 30), "window closed")]
    else:
        assert opened == [("a", (8, 0))]
        assert [(event.name, local(event)) for event in played.of(WindowSkipped)] == [("b", (9, 0))]


async def test_a_window_over_midnight() -> None:
    plan = schedule(
        windows=[{"days": ["mon"], "start": "23:00", "stop": "01:00", "mission": IDLE}],
        on_window_close="stop_now",
    )
    async with simulated_robot() as (robot, device):
        played = await play(robot, plan, MONDAY.replace(hour=22, minute=59), 2.1 * 3600, device)
    [opened], [closed] = played.of(WindowOpened), played.of(WindowClosed)
    assert local(opened) == (23, 0)
    assert closed.at.astimezone(BERLIN).date() == MONDAY.date() + timedelta(days=1)
    assert local(closed) == (1, 0)


async def test_a_window_across_the_spring_dst_change() -> None:
    # Europe/Berlin, Sunday 2026-03-29: 02:00 CET becomes 03:00 CEST; 02:30 does not exist.
    plan = schedule(
        windows=[
            {"days": ["sun"], "start": "01:00", "stop": "04:00", "mission": IDLE, "name": "night"},
            {"days": ["sun"], "start": "02:30", "stop": "05:00", "mission": IDLE, "name": "gap",
             "on_overlap": "wait"},
        ],
        on_window_close="stop_now",
    )  # fmt: skip
    start = datetime(2026, 3, 29, 0, 59, tzinfo=BERLIN)
    async with simulated_robot() as (robot, device):
        played = await play(robot, plan, start, 3 * 3600 + 120, device)
    [night, gap] = played.of(WindowClosed)
    # 01:00 CET to 04:00 CEST is two hours of real time (compared in UTC: one tzinfo
    # on both sides would subtract wall times).
    opened = played.of(WindowOpened)
    took = night.at.astimezone(timezone.utc) - opened[0].at.astimezone(timezone.utc)
    assert took.total_seconds() == pytest.approx(7200, abs=1)
    assert local(night) == (4, 0)
    assert gap.name == "gap"
    # 02:30 is skipped by the clocks: the window would open at 03:00; it waits for night.
    assert local(opened[1]) == (4, 0)
    assert local(gap) == (5, 0)


async def test_an_excluded_date_opens_no_window() -> None:
    plan = schedule(
        windows=[{"days": "every day", "start": "23:50", "stop": "23:55", "mission": IDLE}],
        exclude=["2026-03-23"],
    )
    async with simulated_robot() as (robot, device):
        played = await play(robot, plan, MONDAY.replace(hour=23, minute=49), 120, device)
    assert [local(event) for event in played.of(Excluded)] == [(23, 50)]
    assert played.of(WindowOpened) == []
    assert played.runs.calls == []


async def _by_fail_after(run: Any) -> None:
    with pytest.raises(TimeoutError), anyio.fail_after(200):
        await run()


async def _by_move_on_after(run: Any) -> None:
    with anyio.move_on_after(200) as scope:
        await run()
    assert scope.cancelled_caught


async def _by_asyncio_timeout(run: Any) -> None:
    with pytest.raises(TimeoutError):
        async with asyncio.timeout(200):  # type: ignore[attr-defined, unused-ignore]
            await run()


async def _by_task_cancel(run: Any) -> None:
    task = asyncio.ensure_future(run())
    await asyncio.sleep(200)
    task.cancel()
    with pytest.raises(asyncio.CancelledError):
        await task


async def _by_failing_sibling(run: Any) -> None:
    async def fail() -> None:
        await asyncio.sleep(200)
        raise RuntimeError("sibling")

    async def both() -> None:
        async with anyio.create_task_group() as group:
            group.start_soon(run)
            group.start_soon(fail)

    # an ExceptionGroup (the exceptiongroup backport's on Python 3.10)
    with pytest.raises(Exception, match="unhandled errors") as caught:
        await both()
    assert [str(error) for error in getattr(caught.value, "exceptions", [])] == ["sibling"]


ROUTES = [
    _by_fail_after,
    _by_move_on_after,
    _by_asyncio_timeout,
    _by_task_cancel,
    _by_failing_sibling,
]


@pytest.mark.parametrize("route", ROUTES, ids=[route.__name__[4:] for route in ROUTES])
async def test_cancelling_run_schedule_stops_the_robot(route: Any) -> None:
    import sys

    if route is _by_asyncio_timeout and sys.version_info < (3, 11):
        pytest.skip("asyncio.timeout is Python 3.11+")
    plan = schedule(
        windows=[{"days": "every day", "start": "08:00", "stop": "18:00", "mission": PATROL}]
    )
    runs = FakeRuns([])
    async with simulated_robot() as (robot, device):

        async def run() -> None:
            await run_schedule(robot, plan, now=MONDAY.replace(hour=8), runner=fake_runner(runs))

        device.clear()
        await route(run)
        stops = device.received()
        device.clear()
        await device.advance(5)
        assert device.received() == []  # nothing more is sent: nothing runs
        status = robot.status
    assert runs.calls
    assert status is not None
    assert not status.goal_active
    assert status.current_speed_x == 0
    assert status.current_speed_theta == 0
    assert any(isinstance(command, Stop) for command in stops)
