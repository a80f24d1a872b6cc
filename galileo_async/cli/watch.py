"""Commands that only watch: ``status`` (once or --watch) and the live ``monitor`` dashboard."""

from __future__ import annotations

from collections import deque
from collections.abc import AsyncIterator
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import anyio
import typer
from rich.console import RenderableType
from rich.live import Live

from ..errors import ConnectionLost, GalileoTimeout, InvalidArgument, NotReady
from ..events import ConnectionLostEvent, Event
from ..models import GalileoStatus
from .goals import aclose
from .map_model import MapModel, known_targets
from .map_render import save_svg
from .metrics_opt import MetricsOption, metrics_address
from .monitor_screen import FULL_ROWS, MonitorView, keys_pressed
from .render import (
    event_dict,
    event_text,
    link_event_text,
    status_line,
    status_record,
)
from .runner import (
    ExitCode,
    Settings,
    err_console,
    fail,
    out_console,
    print_json,
    run_robot,
    settings_of,
    timestamp,
)

if TYPE_CHECKING:
    from ..robot import Robot

__all__ = ["SvgOption", "TargetsOption", "map_model", "monitor", "status"]

#: How many recent events the monitor keeps on screen.
RECENT_EVENTS = 10
#: Dashboard refreshes per second.
MONITOR_REFRESH = 8.0
#: Seconds `galileo status` waits for the navigation system behind placeholder frames.
FIRST_REPORT_TIMEOUT = 5.0


def status(
    ctx: typer.Context,
    watch: Annotated[bool, typer.Option("--watch", "-w", help="Keep printing.")] = False,
    interval: Annotated[
        float, typer.Option(min=0.02, help="Seconds between lines with --watch.")
    ] = 0.5,
    count: Annotated[
        int | None, typer.Option(min=1, help="Stop after this many lines with --watch.")
    ] = None,
    reconnect: Annotated[
        bool,
        typer.Option(
            "--reconnect/--no-reconnect",
            help="With --watch: reconnect after a drop, or exit 7 at once.",
        ),
    ] = True,
    json_output: Annotated[bool, typer.Option("--json", help="JSON output.")] = False,
) -> None:
    """Show the latest status (every field), or one line per interval with --watch.

    With --watch, link health (stale, connection lost / restored) goes to stderr, or to
    stdout as JSON event lines with --json.
    """
    settings = settings_of(ctx)
    settings.json = settings.json or json_output
    console = out_console()
    if watch and not reconnect:
        settings.extra["reconnect"] = False

    async def body(robot: Robot) -> int:
        if not watch:
            latest = robot.status or await first_report(robot)
            if settings.json:
                print_json(settings, {"time": timestamp()} | status_record(latest, robot.link))
            else:
                from .render import status_table

                console.print(status_table(latest))
            return 0
        lost: list[str] = []
        events = robot.events()  # subscribed before the first line: no drop goes unseen
        stream = robot.statuses()
        try:
            async with anyio.create_task_group() as group:
                group.start_soon(_report_link, events, settings, reconnect, lost)
                if await _print_statuses(stream, interval, count, settings, robot.link):
                    group.cancel_scope.cancel()
                    return 0
                # The status stream ended: the store closed, so the event stream ends too
                # once the link events buffered before it are printed.
        finally:
            await aclose(stream)
            await aclose(events)
        raise ConnectionLost(lost[-1] if lost else "the link closed")

    run_robot(settings, body, interrupted=ExitCode.OK, long_running=watch and reconnect)


async def first_report(robot: Robot) -> GalileoStatus:
    """The robot's first status, once the navigation system reports (placeholders come first)."""
    err_console().print("[dim]the link is up; waiting for the navigation system to report…[/]")
    try:
        return await robot.wait_until(lambda _status: True, timeout=FIRST_REPORT_TIMEOUT)
    except GalileoTimeout:
        raise NotReady(
            f"the navigation system has not reported yet (for {FIRST_REPORT_TIMEOUT:g} s the "
            "robot's serial node sent only its placeholder frames)",
            None,
        ) from None


async def _print_statuses(
    stream: AsyncIterator[GalileoStatus],
    interval: float,
    count: int | None,
    settings: Settings,
    link: object,
) -> bool:
    """Print a line per interval; True after ``count`` lines, False when the stream ended."""
    console = out_console()
    printed = 0
    next_at = 0.0
    async for current in stream:
        now = anyio.current_time()
        if now < next_at:
            continue
        next_at = now + interval
        if settings.json:
            print_json(settings, {"time": timestamp()} | status_record(current, link))
        else:
            console.print(status_line(current), markup=False)
        printed += 1
        if count is not None and printed >= count:
            return True
    return False


async def _report_link(
    events: AsyncIterator[Event], settings: Settings, reconnecting: bool, lost: list[str]
) -> None:
    """Print link health events (stderr, or JSON lines on stdout); remember loss reasons."""
    started = anyio.current_time()
    async for event in events:
        text = link_event_text(event, reconnecting=reconnecting)
        if text is None:
            continue
        if isinstance(event, ConnectionLostEvent):
            lost.append(event.reason)
        if settings.json:
            print_json(settings, event_line(event, anyio.current_time() - started))
        else:
            err_console().print(text, markup=False, style="yellow")


#: The --targets option of both monitors.
TargetsOption = Annotated[
    Path | None,
    typer.Option("--targets", help="CSV of known targets for the map: id,x,y (metres)."),
]
#: The --svg option of both monitors.
SvgOption = Annotated[
    Path | None, typer.Option("--svg", help="On exit, write the last screen as an SVG file.")
]


def map_model(urls: list[str], targets: Path | None) -> MapModel:
    """The map of a monitor; a bad --targets file exits 2 before anything is opened."""
    try:
        return known_targets(urls, targets)
    except InvalidArgument as exc:
        fail(str(exc), ExitCode.USAGE)


def monitor(
    ctx: typer.Context,
    duration: Annotated[
        float | None, typer.Option(min=0.1, help="Stop after seconds (default: Ctrl-C).")
    ] = None,
    targets: TargetsOption = None,
    svg: SvgOption = None,
    json_output: Annotated[
        bool, typer.Option("--json", help="JSON lines: a status a second, and every event.")
    ] = False,
    metrics: MetricsOption = None,
) -> None:
    """Live dashboard and map (keys: q quit, m map on/off, ? help); --json: JSON lines."""
    serve = metrics_address(metrics)
    settings = settings_of(ctx)
    settings.json = settings.json or json_output
    model = map_model([settings.url], targets)
    view = MonitorView()

    async def body(robot: Robot) -> int:
        started = anyio.current_time()
        recent: deque[tuple[float, str]] = deque(maxlen=RECENT_EVENTS)
        latest: list[GalileoStatus | None] = [robot.status]
        console = out_console()

        async def follow_events() -> None:
            stream = robot.events()
            try:
                async for event in stream:
                    if settings.json:
                        print_json(settings, event_line(event, anyio.current_time() - started))
                    recent.append((anyio.current_time() - started, event_text(event)))
            finally:
                await aclose(stream)

        async def follow_statuses() -> None:
            stream = robot.statuses()
            try:
                async for current in stream:
                    latest[0] = current
                    model.update("robot", current)
            finally:
                await aclose(stream)

        def screen() -> RenderableType:
            return view.screen(
                latest[0], robot.link, list(recent), url=settings.url, model=model,
                rows=console.size.height if console.is_terminal else FULL_ROWS,
            )  # fmt: skip

        try:
            async with anyio.create_task_group() as group:
                group.start_soon(follow_events)
                group.start_soon(follow_statuses)
                deadline = None if duration is None else started + duration
                if settings.json:
                    while await _tick(deadline, 1.0):
                        if latest[0] is not None:
                            record = status_record(latest[0], robot.link)
                            print_json(settings, {"time": timestamp()} | record)
                else:
                    with (
                        keys_pressed(view.press),
                        Live(screen(), console=console, refresh_per_second=MONITOR_REFRESH) as live,
                    ):
                        while not view.quit and await _tick(deadline, 1 / MONITOR_REFRESH):
                            live.update(screen())
                group.cancel_scope.cancel()
        finally:
            if svg is not None:
                save_svg(screen(), svg, title=f"galileo monitor {settings.url}")
        return 0

    run_robot(settings, body, interrupted=ExitCode.OK, long_running=True, metrics=serve)


def event_line(event: Event, seconds: float) -> dict[str, Any]:
    """A JSON event line after ``port``: time, seconds since the command started, the event."""
    return {"time": timestamp(), "t": round(seconds, 3)} | event_dict(event)


async def _tick(deadline: float | None, period: float) -> bool:
    """Sleep one period (less when the deadline is nearer); False once the deadline passed."""
    if deadline is None:
        await anyio.sleep(period)
        return True
    left = deadline - anyio.current_time()
    if left <= 0:
        return False
    await anyio.sleep(min(period, left))
    return True
