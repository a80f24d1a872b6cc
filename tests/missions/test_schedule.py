"""run_schedule with the real runner on the virtual clock: windows, charging, closing, DST."""

from __future__ import annotations

import asyncio
from datetime import datetime, timedelta, timezone
from typing import Any
from zoneinfo import ZoneInfo

import pytest

from galileo_async import ChargeStatus, Robot
from galileo_async.missions.events import LoopStarted, MissionEnded, StepEnded, StepStarted
from galileo_async.missions.report import MissionRejected
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
from galileo_async.protocol import Cancel, Stop
from galileo_async.testing import SimulatedDevice, simulated_robot
from tests.support.cancel_ways import WAYS, stop_waiting

BERLIN = ZoneInfo("Europe/Berlin")
#: A Monday.
MONDAY = datetime(2026, 3, 23, tzinfo=BERLIN)
_ON_DOCK = (ChargeStatus.FINDING_DOCK, ChargeStatus.DOCKING, ChargeStatus.CHARGING,
            ChargeStatus.CHARGED)  # fmt: skip

PATROL = {
    "mission": "patrol",
    "steps": [{"loop": {"steps": [{"goto": 1}, {"dwell": 30}, {"goto": 2}, {"dwell": 30}]}}],
}
IDLE = {"mission": "idle", "steps": [{"loop": {"steps": [{"dwell": 60}]}}]}


def schedule(**fields: Any) -> Schedule:
    return Schedule.model_validate({"time_zone": "Europe/Berlin", **fields})


class Played:
    """run_schedule's events (the schedule's and the runner's) in order."""

    def __init__(self) -> None:
        self.events: list[object] = []

    def of(self, kind: type[Any]) -> list[Any]:
        return [event for event in self.events if isinstance(event, kind)]

    def resumes(self) -> list[tuple[StepStarted | None, StepStarted]]:
        """Each Resumed: the step started last before its pause, and the first after it."""
        found = []
        last: StepStarted | None = None
        for index, event in enumerate(self.events):
            if isinstance(event, ChargingPause):
                before = last
            elif isinstance(event, Resumed):
                after = next(e for e in self.events[index:] if isinstance(e, StepStarted))
                found.append((before, after))
            elif isinstance(event, StepStarted):
                last = event
            elif isinstance(event, WindowOpened):
                last = None
        return found


async def play(
    robot: Robot, plan: Schedule, start: datetime, seconds: float, device: SimulatedDevice
) -> Played:
    played = Played()
    task = asyncio.ensure_future(
        run_schedule(robot, plan, now=start, on_progress=played.events.append)
    )
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
    # The mission loops: its loop turned many times in each window.
    assert max(event.iteration for event in played.of(LoopStarted)) > 50
    # Charging from the battery threshold, mid-loop, in both windows; each pause resumed.
    pauses = played.of(ChargingPause)
    assert {pause.window for pause in pauses} == {0, 1}
    assert all(pause.reason == "battery low" for pause in pauses)
    assert len(played.of(Resumed)) == len(pauses)
    resumes = played.resumes()
    assert resumes
    for before, after in resumes:
        if before is None:  # low when the window opened: its first run starts afresh
            assert (after.path, after.loops) == ("steps[0].loop.steps[0]", {"steps[0]": 1})
        else:  # the journal: the same step of the same loop turn
            assert (after.path, after.loops) == (before.path, before.loops)
    assert any(before is not None for before, _ in resumes)
    assert all(event.report.ending == "cancelled" for event in played.of(MissionEnded))
    assert status is not None
    assert status.charge_status in _ON_DOCK  # the stop pose at 18:00: the dock


async def test_docking_started_outside_pauses_the_mission_until_charged() -> None:
    plan = schedule(
        windows=[{"days": "every day", "start": "08:00", "stop": "09:00", "mission": PATROL}]
    )
    async with simulated_robot() as (robot, device):
        played = Played()
        task = asyncio.ensure_future(
            run_schedule(robot, plan, now=MONDAY.replace(hour=8), on_progress=played.events.append)
        )
        await device.advance(100)
        device.go_charge()  # the robot heads for the dock by itself
        await device.advance(600)
        task.cancel()
        with pytest.raises(asyncio.CancelledError):
            await task
    assert [pause.reason for pause in played.of(ChargingPause)] == ["docked"]
    assert len(played.of(Resumed)) == 1
    [(before, after)] = played.resumes()
    assert before is not None
    assert (after.path, after.loops) == (before.path, before.loops)


async def test_a_resume_after_charging_starts_at_the_step_where_it_stopped() -> None:
    errand = {
        "mission": "errand",
        "steps": [{"goto": 1}, {"dwell": 30}, {"goto": 2}, {"dwell": 600}, {"goto": 3}],
    }
    plan = schedule(
        windows=[{"days": "every day", "start": "08:00", "stop": "09:00", "mission": errand}]
    )
    async with simulated_robot() as (robot, device):
        played = Played()
        task = asyncio.ensure_future(
            run_schedule(robot, plan, now=MONDAY.replace(hour=8), on_progress=played.events.append)
        )
        await robot.wait_until(lambda status: status.target_num_id == 2 and not status.goal_active,
                               timeout=600)  # fmt: skip
        await device.advance(60)  # into the long dwell
        device.go_charge()
        await device.advance(1800)
        task.cancel()
        with pytest.raises(asyncio.CancelledError):
            await task
    pause = played.events.index(played.of(ChargingPause)[0])
    started = [e.path for e in played.events[:pause] if isinstance(e, StepStarted)]
    again = [e.path for e in played.events[pause:] if isinstance(e, StepStarted)]
    assert started == ["steps[0]", "steps[1]", "steps[2]", "steps[3]"]
    assert again == ["steps[3]", "steps[4]"]  # nothing before the dwell is driven again
    first, second = played.of(MissionEnded)
    assert (first.report.ending, first.report.resumed_at) == ("cancelled", None)
    assert (second.report.ending, second.report.resumed_at) == ("completed", "steps[3]")
    [closed] = played.of(WindowClosed)
    assert closed.reason == "mission ended"


@pytest.mark.parametrize("policy", ["finish_step", "stop_now"])
async def test_window_close_finishes_the_step_or_stops_now(policy: str) -> None:
    long_dwell = {"mission": "wait", "steps": [{"dwell": 10}, {"dwell": 350}, {"dwell": 10}]}
    # finish_step, then a target as the stop pose; stop_now, then the dock.
    stop_pose = 3 if policy == "finish_step" else "dock"
    plan = schedule(
        windows=[
            {"days": "every day", "start": "08:00", "stop": "08:05", "mission": long_dwell,
             "stop_pose": stop_pose}
        ],
        on_window_close=policy,
    )  # fmt: skip
    async with simulated_robot() as (robot, device):
        played = await play(robot, plan, MONDAY.replace(hour=8), 1200, device)
        status = robot.status
    [closed] = played.of(WindowClosed)
    assert closed.reason == "window closed"
    stop = MONDAY.replace(hour=8, minute=5)
    # steps[1] ends at 08:06:00; the stop pose is a few seconds away
    assert (closed.at > stop + timedelta(seconds=60)) is (policy == "finish_step")
    assert closed.at < stop + timedelta(seconds=90)
    done = [e.step.path for e in played.of(StepEnded) if e.step.ending == "done"]
    assert done == (["steps[0]", "steps[1]"] if policy == "finish_step" else ["steps[0]"])
    assert status is not None
    if policy == "finish_step":
        assert status.target_num_id == 3
    else:
        assert status.charge_status in _ON_DOCK


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
    assert played.of(StepStarted) == []


@pytest.mark.parametrize("how", WAYS)
async def test_stopping_run_schedule_every_way_leaves_the_robot_stopped(how: str) -> None:
    plan = schedule(
        windows=[{"days": "every day", "start": "08:00", "stop": "18:00", "mission": PATROL}]
    )
    played = Played()
    async with simulated_robot() as (robot, device):

        async def run() -> None:
            await run_schedule(
                robot, plan, now=MONDAY.replace(hour=8), on_progress=played.events.append
            )

        device.clear()
        await stop_waiting(how, run, 200)
        stops = device.received()
        device.clear()
        await device.advance(30)
        assert device.received() == []  # nothing more is sent: nothing runs
        status = robot.status
    assert played.of(StepStarted)
    assert status is not None
    assert not status.goal_active
    assert status.current_speed_x == 0
    assert status.current_speed_theta == 0
    assert any(isinstance(command, Stop) for command in stops)


async def test_a_mission_the_link_cannot_run_ends_the_schedule_before_anything_moves() -> None:
    plan = schedule(
        windows=[{"days": "every day", "start": "08:00", "stop": "09:00",
                  "mission": {"mission": "hello", "steps": [{"say": "hello"}]}}]
    )  # fmt: skip
    async with simulated_robot() as (robot, device):
        device.clear()
        with pytest.raises(MissionRejected, match="say"):
            await run_schedule(robot, plan, now=MONDAY.replace(hour=8))
        sent = device.received()
    # Nothing but robot.stop() on the way out (a cancel and a stop): no goal was sent.
    assert {type(command) for command in sent} == {Cancel, Stop}
