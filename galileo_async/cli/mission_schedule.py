"""``galileo mission schedule``: a schedule's windows on a robot until stopped, or --sim.

The command function and ``register``, which adds it to the ``galileo mission`` group.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from datetime import datetime, timedelta, tzinfo
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer

from ..missions.capabilities import REST_API, needs
from ..missions.events import LoopStarted, MissionEnded, MissionEvent, StepEnded
from ..missions.model import step_paths
from ..missions.report import MissionRejected
from ..missions.schedule import (
    ChargingPause,
    Excluded,
    Resumed,
    ScheduleEvent,
    WindowClosed,
    WindowOpened,
    WindowSkipped,
)
from .metrics_opt import MetricsOption, metrics_address
from .mission import PointsOption, file_failure, plan_errors, point_source
from .mission_run import event_line, print_rejected
from .output import out_console, timestamp
from .runner import ExitCode, fail, run, run_robot, settings_of

if TYPE_CHECKING:
    from ..missions.schedule_model import Schedule
    from ..robot import Robot
    from ..testing.robot import SimLink

__all__ = ["mission_schedule", "register"]

#: Days --sim plays when --days is not given.
SIM_DAYS = 1

Event = ScheduleEvent | MissionEvent


def _load(settings: Any, file: Path, points: Path | None) -> Schedule:
    """The schedule in ``file`` (a schedule file, or the vendor's timeTask.json with its
    paths' ``points``); a file that does not load: every problem, exit 2."""
    from ..missions.files import MissionFileError
    from ..missions.importers import detect_format, load_plan
    from ..missions.schedule_model import load_schedule, schedule_from_plan

    with plan_errors():
        try:
            if detect_format(file) != "timetask":
                return load_schedule(file)
            if points is None:
                fail(f"{file}: a timeTask.json needs --points (its paths' points)", ExitCode.USAGE)
            plan = load_plan(file, plan_format="timetask", points=point_source(points))
            return schedule_from_plan(plan, name=file.stem)
        except (OSError, UnicodeDecodeError) as exc:
            fail(f"{file}: {getattr(exc, 'strerror', None) or exc}", ExitCode.USAGE)
        except MissionFileError as exc:
            file_failure(settings, exc)
        except ValueError as exc:  # a timeTask.json's windows that make no schedule
            fail(f"{file}: {exc}", ExitCode.USAGE)


def _schedule_line(event: ScheduleEvent, zone: tzinfo) -> str:
    """The text of a schedule event (its wall time is the line's prefix)."""
    if isinstance(event, WindowOpened):
        closes = event.closes.astimezone(zone).strftime("%H:%M")
        return f"{_window(event.window, event.name)} opened, closes at {closes}"
    if isinstance(event, WindowClosed):
        return f"{_window(event.window, event.name)} closed: {event.reason}"
    if isinstance(event, WindowSkipped):
        return f"{_window(event.window, event.name)} skipped: another window runs"
    if isinstance(event, Excluded):
        return f"{_window(event.window, event.name)} not opened: the date is excluded"
    if isinstance(event, ChargingPause):
        return f"charging ({event.reason}{_volts(event.volts)}): the mission pauses"
    if isinstance(event, Resumed):
        return f"charged{_volts(event.volts)}: the mission resumes where it stopped"
    return type(event).__name__


def _window(index: int, name: str | None) -> str:
    return f"window {index}" + (f" ({name})" if name else "")


def _volts(volts: float | None) -> str:
    return "" if volts is None else f", {volts:.2f} V"


def _printer(
    as_json: bool, zone: tzinfo, now: Callable[[], datetime], steps: bool
) -> Callable[[object], None]:
    """A progress callback printing a line per event (``steps``: the steps' lines too)."""
    console = out_console()

    def show(event: object) -> None:
        if as_json:
            if isinstance(event, (ScheduleEvent, MissionEvent)):
                line = json.dumps({"time": timestamp(), **event.to_json()})
                console.print(line, markup=False, soft_wrap=True, highlight=False)
            return
        if isinstance(event, ScheduleEvent):
            at, text = event.at, _schedule_line(event, zone)
        elif isinstance(event, MissionEnded) or (
            steps and isinstance(event, (StepEnded, LoopStarted))
        ):
            at, text = now(), event_line(event) or ""
        else:
            return
        stamp = at.astimezone(zone).strftime("%Y-%m-%d %H:%M:%S")
        console.print(f"{stamp} {text}", markup=False, soft_wrap=True, highlight=False)

    return show


def _start(value: str | None, zone: tzinfo) -> datetime:
    """--start as an aware datetime in the schedule's zone (now when not given)."""
    if value is None:
        return datetime.now(zone)
    try:
        start = datetime.strptime(value, "%Y-%m-%dT%H:%M")
    except ValueError:
        message = f"{value!r} is not YYYY-MM-DDTHH:MM"
        raise typer.BadParameter(message, param_hint="--start") from None
    return start.replace(tzinfo=zone)


def mission_schedule(
    ctx: typer.Context,
    file: Annotated[
        Path,
        typer.Argument(
            help="The schedule file (YAML), or the vendor's timeTask.json.", dir_okay=False
        ),
    ],
    sim: Annotated[
        bool,
        typer.Option(
            "--sim",
            help="Play it on the built-in simulator on a virtual clock (a day in seconds) and "
            "print the timeline.",
        ),
    ] = False,
    days: Annotated[
        float, typer.Option("--days", min=0.01, help="--sim: how many days to play.")
    ] = SIM_DAYS,
    start: Annotated[
        str | None,
        typer.Option(
            "--start",
            metavar="YYYY-MM-DDTHH:MM",
            help="--sim: the wall time it starts at, in the schedule's zone (default now).",
        ),
    ] = None,
    points: PointsOption = None,
    json_output: Annotated[
        bool, typer.Option("--json", help="A JSON line per event (windows, charging, steps).")
    ] = False,
    metrics: MetricsOption = None,
) -> None:
    """Run a schedule's windows until stopped, with a line per window, step and charging.

    Ctrl-C, SIGTERM: the robot is stopped, 130/143; 2: the file does not load or a mission
    is rejected before anything moved; other failures as ``mission run``'s.
    """
    from ..missions.schedule_model import zone_of

    serve = metrics_address(metrics)
    if sim and serve is not None:
        fail("--metrics is for a robot's schedule, not --sim", ExitCode.USAGE)
    settings = settings_of(ctx)
    settings.json = settings.json or json_output
    schedule = _load(settings, file, points)
    zone = zone_of(schedule)
    if sim:
        first = _start(start, zone)

        async def simulated() -> int:
            return await _play(schedule, first, days, settings.json, zone)

        run(settings, simulated)
    if start is not None:
        fail("--start is for --sim: a robot's schedule runs on the host's clock", ExitCode.USAGE)

    async def body(robot: Robot) -> int:
        from ..missions.schedule import run_schedule

        show = _printer(settings.json, zone, lambda: datetime.now(zone), steps=True)
        try:
            await run_schedule(robot, schedule, on_progress=show)
        except MissionRejected as exc:
            return print_rejected(exc)
        return int(ExitCode.OK)  # run_schedule returns only by cancellation

    run_robot(settings, body, navigation=None, moving=True, metrics=serve)


async def _play(
    schedule: Schedule, first: datetime, days: float, as_json: bool, zone: tzinfo
) -> int:
    """``--sim``: ``days`` of the schedule on simulated_robot() (http:// when a step needs it)."""
    import asyncio

    from ..missions.schedule import run_schedule
    from ..testing import simulated_robot

    steps = [
        step
        for window in schedule.windows
        if not isinstance(window.mission, str)
        for _, step in step_paths(window.mission.steps)
    ]
    link: SimLink = "http" if any(REST_API in needs(step) for step in steps) else "sim"
    async with simulated_robot(link=link) as (robot, device):
        loop = asyncio.get_running_loop()
        t0 = loop.time()

        def now() -> datetime:
            return first + timedelta(seconds=loop.time() - t0)

        show = _printer(as_json, zone, now, steps=False)
        task = asyncio.ensure_future(run_schedule(robot, schedule, now=first, on_progress=show))
        try:
            await device.advance(days * 24 * 3600)
        finally:
            task.cancel()
            await asyncio.wait({task})
        if not task.cancelled() and task.exception() is not None:
            error = task.exception()
            if isinstance(error, MissionRejected):
                return print_rejected(error)
            assert error is not None
            raise error
    return int(ExitCode.OK)


def register(mission_app: typer.Typer) -> None:
    """Add ``schedule`` to the ``galileo mission`` group."""
    mission_app.command("schedule")(mission_schedule)
