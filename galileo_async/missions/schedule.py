"""run_schedule(): a schedule's windows on a robot, on the loop's clock (no polling).

The next window edge is computed and slept until on the event loop's clock, so a
virtual clock (galileo_async.testing) plays a day in seconds. Wall time is loop time
plus an anchor taken at the start (``_Wall``): the one conversion.
"""

from __future__ import annotations

import asyncio
import tempfile
from collections.abc import Callable
from dataclasses import dataclass, fields
from datetime import datetime, timedelta, timezone
from pathlib import Path
from typing import TYPE_CHECKING, Any

import anyio

from ..errors import GalileoError
from ..models import ChargeStatus, GalileoStatus
from .events import MissionEvent, StepEnded, StepStarted
from .exit_stop import EXIT_STOP_TIMEOUT, exit_stop
from .model import Mission
from .report import MissionReport
from .runner import run_mission
from .schedule_model import Occurrence, Schedule, occurrences, zone_of

if TYPE_CHECKING:
    from ..robot import Robot

__all__ = [
    "ChargingPause",
    "Excluded",
    "Resumed",
    "ScheduleEvent",
    "WindowClosed",
    "WindowOpened",
    "WindowSkipped",
    "run_schedule",
]

#: A wall time this close to an edge counts as the edge (loop time is a float).
_EDGE = timedelta(milliseconds=1)
_DOCKING = (ChargeStatus.FINDING_DOCK, ChargeStatus.DOCKING)
_ON_DOCK = (ChargeStatus.CHARGING, ChargeStatus.CHARGED)


@dataclass(frozen=True)
class ScheduleEvent:
    """Something the schedule did, at ``at`` (aware, in the schedule's zone)."""

    at: datetime

    @property
    def kind(self) -> str:
        """The event's name in JSON lines ("window_opened" …)."""
        name = type(self).__name__
        return "".join(f"_{c.lower()}" if c.isupper() else c for c in name).lstrip("_")

    def to_json(self) -> dict[str, Any]:
        """A JSON-able dict: ``event`` (the kind), the fields, instants in ISO 8601; a
        closed window's report without its steps."""
        data: dict[str, Any] = {"event": self.kind}
        for item in fields(self):
            value = getattr(self, item.name)
            if isinstance(value, datetime):
                value = value.isoformat()
            elif isinstance(value, MissionReport):
                value = value.model_dump(mode="json", exclude={"steps"})
            data[item.name] = value
        return data


@dataclass(frozen=True)
class WindowOpened(ScheduleEvent):
    """A window opened: its mission starts."""

    window: int
    name: str | None
    closes: datetime


@dataclass(frozen=True)
class WindowClosed(ScheduleEvent):
    """A window's run ended: ``reason`` says why; ``report`` the mission's, when it ended."""

    window: int
    name: str | None
    reason: str
    report: MissionReport | None = None


@dataclass(frozen=True)
class WindowSkipped(ScheduleEvent):
    """A window opened while another ran, and its on_overlap is skip."""

    window: int
    name: str | None


@dataclass(frozen=True)
class Excluded(ScheduleEvent):
    """A window did not open: its day is excluded."""

    window: int
    name: str | None


@dataclass(frozen=True)
class ChargingPause(ScheduleEvent):
    """The mission paused for charging: "battery low" or "docked" (charging seen)."""

    window: int
    reason: str
    volts: float | None


@dataclass(frozen=True)
class Resumed(ScheduleEvent):
    """Charging ended: the mission resumes where it paused."""

    window: int
    volts: float | None


Progress = Callable[[object], None]


class _Wall:
    """Wall time from the loop's clock: an anchor taken once, at the start."""

    def __init__(self, now: datetime | None, zone: Any) -> None:
        if now is not None and now.tzinfo is None:
            raise ValueError("now must be an aware datetime")
        self.zone = zone
        self._anchor = (now or datetime.now(timezone.utc)).astimezone(timezone.utc)
        self._loop = asyncio.get_running_loop()
        self._t0 = self._loop.time()

    def now(self) -> datetime:
        """Now, aware, in the schedule's zone."""
        elapsed = timedelta(seconds=self._loop.time() - self._t0)
        return (self._anchor + elapsed).astimezone(self.zone)

    def until(self, instant: datetime) -> float:
        """Seconds of loop time from now until ``instant`` (0 when it has passed)."""
        return max(0.0, (instant - self.now()).total_seconds())

    async def sleep_until(self, instant: datetime) -> None:
        """Return at ``instant``: the schedule's own edge, on the loop's clock."""
        await asyncio.sleep(self.until(instant))


def _volts(status: GalileoStatus | None) -> float | None:
    return status.power if status is not None and status.power is not None else None


class _Run:
    """One run_schedule(): the state shared by its windows."""

    def __init__(
        self,
        robot: Robot,
        schedule: Schedule,
        missions: list[Mission],
        wall: _Wall,
        on_progress: Progress | None,
        journals: Path,
    ) -> None:
        self.robot = robot
        self.schedule = schedule
        self.missions = missions
        self.wall = wall
        self.on_progress = on_progress
        self.journals = journals
        self._step_ended: asyncio.Event | None = None
        self._charge_step = False

    def emit(self, event: object) -> None:
        if self.on_progress is not None:
            self.on_progress(event)

    def _mission_event(self, event: MissionEvent) -> None:
        self.emit(event)
        if isinstance(event, StepStarted) and event.action == "charge":
            self._charge_step = True  # the mission's own charging is no pause
        elif isinstance(event, StepEnded):
            self._charge_step = False
            if self._step_ended is not None:
                self._step_ended.set()

    # ------------------------------------------------------------------ the days
    async def run(self) -> None:
        """Every window from now on, in order; returns only by cancellation."""
        now = self.wall.now()
        last: Occurrence | None = None
        ended = now
        for occurrence in occurrences(self.schedule, self.wall.zone, now.date() - timedelta(1)):
            if occurrence.stop <= ended + _EDGE:
                continue
            if last is not None and occurrence.key <= last.key:
                continue
            window = self.schedule.windows[occurrence.index]
            if occurrence.start > self.wall.now() + _EDGE:
                await self.wall.sleep_until(occurrence.start)
            elif last is not None and occurrence.start < ended and window.on_overlap == "skip":
                self.emit(WindowSkipped(self.wall.now(), occurrence.index, window.name))
                last = occurrence
                continue
            if occurrence.excluded:
                self.emit(Excluded(self.wall.now(), occurrence.index, window.name))
                last = occurrence
                continue
            await self.window(occurrence)
            last, ended = occurrence, self.wall.now()

    def _preempted_at(self, running: Occurrence) -> Occurrence | None:
        """The first window that opens during ``running`` and preempts it, if any."""
        for later in occurrences(self.schedule, self.wall.zone, running.day):
            if later.start >= running.stop:
                return None
            window = self.schedule.windows[later.index]
            if later.key > running.key and not later.excluded and window.on_overlap == "preempt":
                return later
        return None

    # ------------------------------------------------------------------ one window
    async def window(self, occurrence: Occurrence) -> None:
        """Run a window's mission until it ends or the window closes; then the stop pose."""
        index = occurrence.index
        window = self.schedule.windows[index]
        preempting = self._preempted_at(occurrence)
        closes = preempting.start if preempting is not None else occurrence.stop
        stop = occurrence.stop.astimezone(self.wall.zone)
        self.emit(WindowOpened(self.wall.now(), index, window.name, stop))
        journal = self.journals / f"window-{index}-{occurrence.day.isoformat()}.journal"
        reason, report = await self._mission(index, closes, journal)
        if preempting is not None and reason == "window closed":
            reason = "preempted"
        elif reason in ("mission ended", "window closed"):
            await self._stop_pose(window.stop_pose)
        self.emit(WindowClosed(self.wall.now(), index, window.name, reason, report))

    async def _mission(
        self, index: int, closes: datetime, journal: Path
    ) -> tuple[str, MissionReport | None]:
        """Run (and resume after each charging pause) until the mission ends or ``closes``."""
        resume = started = False
        while True:
            battery = self.schedule.battery
            volts = _volts(self.robot.status)
            if battery is not None and volts is not None and battery.low(volts):
                if not await self._charge(index, "battery low", closes):
                    return "battery low", None
                resume = started
            mission = asyncio.ensure_future(
                run_mission(
                    self.robot, self.missions[index], journal=journal, resume=resume,
                    on_progress=self._mission_event,
                )
            )  # fmt: skip
            started = True
            watch = asyncio.ensure_future(
                self.robot.wait_until(self._needs_charge, timeout=self._left(closes) + 1)
            )
            try:
                await asyncio.wait(
                    {mission, watch},
                    timeout=self.wall.until(closes),
                    return_when=asyncio.FIRST_COMPLETED,
                )
                charge = watch.done() and not watch.cancelled() and watch.exception() is None
                seen = watch.result() if charge else None
                await _reap(watch)
                if not mission.done():
                    if not charge and self.schedule.on_window_close == "finish_step":
                        await self._finish_step(mission)
                    await _reap(mission)
            finally:
                await _reap(watch)
                await _reap(mission)
            ended = mission.done() and not mission.cancelled()
            failure = mission.exception() if ended else None
            if failure is not None:
                raise failure  # MissionRejected (nothing moved), or a bug: never hidden
            if ended and (not charge or self.wall.now() + _EDGE >= closes):
                return "mission ended", mission.result()
            if not charge:
                return "window closed", None
            reason = (
                "docked"
                if seen is not None and seen.charge_status in (*_DOCKING, *_ON_DOCK)
                else "battery low"
            )
            if not await self._charge(index, reason, closes):
                return reason, None
            resume = True

    async def _finish_step(self, mission: asyncio.Future[Any]) -> None:
        """Wait until the mission's current step ends (within finish_step_timeout)."""
        ended = self._step_ended = asyncio.Event()
        try:
            with anyio.move_on_after(self.schedule.finish_step_timeout):
                ended_wait = asyncio.ensure_future(ended.wait())
                try:
                    await asyncio.wait({ended_wait, mission}, return_when=asyncio.FIRST_COMPLETED)
                finally:
                    await _reap(ended_wait)
        finally:
            self._step_ended = None

    def _needs_charge(self, status: GalileoStatus) -> bool:
        """Charging began (someone docked it) or the battery is below the threshold."""
        if self._charge_step:
            return False
        if status.charge_status in _DOCKING or status.charging:
            return True
        battery = self.schedule.battery
        return battery is not None and status.power is not None and battery.low(status.power)

    def _charged(self, status: GalileoStatus) -> bool:
        battery = self.schedule.battery
        if status.charge_status == ChargeStatus.CHARGED:
            return True
        if status.charge_status in (ChargeStatus.FREE, ChargeStatus.ERROR):
            return True  # taken off the dock, or docking failed: nothing more to wait for
        return battery is not None and status.power is not None and battery.charged(status.power)

    async def _charge(self, index: int, reason: str, closes: datetime) -> bool:
        """Pause for charging until charged; False when the window closes first or it fails."""
        status = self.robot.status
        self.emit(ChargingPause(self.wall.now(), index, reason, _volts(status)))
        on_dock = status is not None and status.charge_status in (*_DOCKING, *_ON_DOCK)
        self._charge_step = False
        try:
            if not on_dock:
                await self._dock(closes)
            status = await self.robot.wait_until(self._charged, timeout=self._left(closes))
            battery = self.schedule.battery
            volts = _volts(status)
            if volts is not None and battery is not None and battery.low(volts):
                return False  # off the dock and still low: no retry loop
            if status.charge_status in _ON_DOCK:
                await self.robot.stop_charging()
        except (GalileoError, asyncio.TimeoutError, TimeoutError):
            return False
        self.emit(Resumed(self.wall.now(), index, volts))
        return True

    def _left(self, closes: datetime) -> float:
        """Seconds until ``closes``, at least a millisecond (a timeout of 0 is refused)."""
        return max(self.wall.until(closes), 0.001)

    async def _dock(self, closes: datetime) -> None:
        """Drive to the dock target (if any) and start docking, within the window."""
        battery = self.schedule.battery
        target = battery.dock_target if battery and battery.dock_target is not None else None
        target = self.schedule.dock_target if target is None else target
        with anyio.fail_after(self._left(closes)):
            if target is not None:
                await self.robot.goto(target)
            await self.robot.start_charging()

    async def _stop_pose(self, pose: int | str | None) -> None:
        """Go to the window's stop pose: a target id, or the dock (stays there if on it)."""
        status = self.robot.status
        if pose is None or (status is not None and status.charge_status in (*_DOCKING, *_ON_DOCK)):
            return
        if pose == "dock":
            if self.schedule.dock_target is not None:
                await self.robot.goto(self.schedule.dock_target)
            await self.robot.start_charging()
        else:
            await self.robot.goto(int(pose))


async def _reap(task: asyncio.Future[Any]) -> None:
    """Cancel ``task`` and wait for it to end, even while cancelled (shielded, bounded)."""
    if not task.done():
        task.cancel()
    with anyio.CancelScope(shield=True), anyio.move_on_after(EXIT_STOP_TIMEOUT * 2):
        await asyncio.wait({task})
    if task.done() and not task.cancelled():
        task.exception()  # retrieved: the outcome is read by the caller where it matters


async def run_schedule(
    robot: Robot,
    schedule: Schedule,
    *,
    on_progress: Progress | None = None,
    now: datetime | None = None,
) -> None:
    """Run ``schedule`` on ``robot`` until cancelled; the robot is stopped on the way out.

    ``now``: the wall time at the start (aware; default the host's clock), from which
    the loop's clock counts on. Each mission runs with ``run_mission`` (a journal per
    window, so a charging pause resumes at its step). ``on_progress`` gets the schedule's
    events and the runner's. Missions must be loaded (``load_schedule`` reads their
    files). Leaving by any route (cancellation, an error of the runner or the robot)
    stops the robot, shielded and within EXIT_STOP_TIMEOUT s.
    """
    missions = []
    for window in schedule.windows:
        if not isinstance(window.mission, Mission):
            raise ValueError(f"window mission {window.mission!r} is not loaded: use load_schedule")
        missions.append(window.mission)
    wall = _Wall(now, zone_of(schedule))
    try:
        with tempfile.TemporaryDirectory(prefix="galileo-schedule-") as journals:
            run = _Run(robot, schedule, missions, wall, on_progress, Path(journals))
            await run.run()
    finally:
        await exit_stop(robot, "the schedule's exit stop")
