"""``galileo demo``: a scripted tour of the driver against the embedded simulator."""

from __future__ import annotations

import asyncio
import time
from collections.abc import Awaitable, Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Annotated

import anyio
import typer
from rich.console import Group
from rich.live import Live
from rich.table import Table
from rich.text import Text

from ..errors import GalileoError, GoalRejected, UnconfirmedOperation
from ..models import TargetStatus
from .goals import aclose
from .map_model import MapModel, known_targets
from .map_render import map_panel
from .ops import start_patrol
from .render import status_line
from .runner import (
    ExitCode,
    checked_port,
    err_console,
    fail,
    is_sim,
    out_console,
    run,
    settings_of,
    with_query,
)
from .signals import stop_on_interrupt

if TYPE_CHECKING:
    from ..robot import Robot

__all__ = ["Step", "demo", "tour"]

#: Default time scale of the demo's simulator: the tour takes ~60 simulated seconds.
DEMO_SPEED = 3.0
#: Real seconds any single step may take before the demo gives up on it.
STEP_TIMEOUT = 40.0
#: Rows of the map the demo shows while the robot drives.
DEMO_MAP_ROWS = 14
#: A target id the default six-target map does not have.
MISSING_TARGET = 42


@dataclass(frozen=True)
class Step:
    """One line of the demo's summary."""

    what: str
    result: str
    seconds: float
    ok: bool


async def _pause_and_resume(robot: Robot, target_id: int) -> str:
    """Go to a target; pause half way for one simulated second, then resume."""
    goal = asyncio.ensure_future(robot.goto(target_id, timeout=STEP_TIMEOUT))
    try:
        first = await robot.wait_until(
            lambda s: (
                s.target_num_id == target_id
                and s.target_status == TargetStatus.WORKING
                and s.target_distance is not None
            ),
            timeout=STEP_TIMEOUT,
        )
        half = (first.target_distance or 0.0) / 2
        await robot.wait_until(
            lambda s: s.target_distance is not None and s.target_distance <= half,
            timeout=STEP_TIMEOUT,
        )
        await robot.pause()
        await _frames(robot, 30)  # 30 frames: one simulated second, whatever the speed
        await robot.resume()
        result = await goal
    finally:
        if not goal.done():
            goal.cancel()
        await asyncio.gather(goal, return_exceptions=True)
    return f"paused half way, resumed, arrived {result.distance or 0.0:.2f} m off"


async def _frames(robot: Robot, count: int) -> None:
    stream = robot.statuses()
    try:
        seen = 0
        with anyio.fail_after(STEP_TIMEOUT):
            async for _ in stream:
                seen += 1
                if seen >= count:
                    return
    finally:
        await aclose(stream)


async def _rejected(robot: Robot) -> str:
    try:
        await robot.goto(MISSING_TARGET, timeout=STEP_TIMEOUT)
    except GoalRejected as exc:
        status = exc.status
        if status is None or status.target_status is None:
            return "rejected, as expected"
        return (
            f"rejected, as expected: target_status {int(status.target_status)}, "
            f"target_num_id {status.target_num_id}"
        )
    raise GalileoError(f"goto({MISSING_TARGET}) should have been rejected")


async def _patrol(robot: Robot, stops: int) -> str:
    """Patrol until ``stops`` targets were reached, then stop patrolling."""
    from ..events import GoalReached

    reached: list[int | None] = []
    events = robot.events()
    try:
        await _unconfirmed_on_v1(robot, start_patrol(robot, 1))
        with anyio.fail_after(STEP_TIMEOUT):
            async for event in events:
                if isinstance(event, GoalReached):
                    reached.append(event.target_id)
                    if len(reached) >= stops:
                        break
    finally:
        await aclose(events)
    await _unconfirmed_on_v1(robot, robot.stop_patrol())
    return "visited targets " + ", ".join(str(target) for target in reached) + ", stopped"


async def _unconfirmed_on_v1(robot: Robot, operation: Awaitable[None]) -> None:
    """Await a patrol command; a layout without loop_status (v1) cannot confirm it: go on."""
    try:
        await operation
    except UnconfirmedOperation:
        if robot.status is None or robot.status.loop_status is not None:
            raise  # the goals reached show whether the patrol runs


async def _arrive(robot: Robot, target_id: int) -> str:
    result = await robot.goto(target_id, timeout=STEP_TIMEOUT)
    return f"arrived, {result.distance or 0.0:.2f} m off"


async def _arrive_point(robot: Robot, x: float, y: float, model: MapModel) -> str:
    result = await robot.goto_point(x, y, timeout=STEP_TIMEOUT)
    model.add_target(result.target_id, x, y, "dynamic")  # this host added it: on the map
    return f"arrived at dynamic target {result.target_id}, {result.distance or 0.0:.2f} m off"


def _plan(robot: Robot, model: MapModel) -> list[tuple[str, Callable[[], Awaitable[str]]]]:
    async def start() -> str:
        await robot.start_navigation(timeout=STEP_TIMEOUT)
        return "navigation open, visual initialised"

    async def stop() -> str:
        await robot.stop_navigation()
        return "navigation closed"

    return [
        ("start navigation", start),
        ("go to target 0", lambda: _arrive(robot, 0)),
        ("go to target 1, pause and resume on the way", lambda: _pause_and_resume(robot, 1)),
        ("go to the point (1.0, -2.0)", lambda: _arrive_point(robot, 1.0, -2.0, model)),
        (f"go to target {MISSING_TARGET} (not on the map)", lambda: _rejected(robot)),
        ("patrol two targets, 1 s dwell", lambda: _patrol(robot, 2)),
        ("stop navigation", stop),
    ]


async def tour(robot: Robot, *, show: bool, model: MapModel | None = None) -> list[Step]:
    """Run every demo step in order; stop at the first failure (``show``: live map too)."""
    steps: list[Step] = []
    model = MapModel() if model is None else model
    plan = _plan(robot, model)
    with Live(Text(""), console=err_console(), transient=True, refresh_per_second=8) as live:
        for number, (what, action) in enumerate(plan, 1):
            label = f"[{number}/{len(plan)}] {what}"
            if not show:
                err_console().print(label, markup=False)
            began = time.monotonic()
            async with anyio.create_task_group() as group:
                if show:
                    group.start_soon(_progress, robot, label, live, model)
                try:
                    result, ok = await action(), True
                except (GalileoError, TimeoutError) as exc:
                    result, ok = f"{type(exc).__name__}: {exc}", False
                group.cancel_scope.cancel()
            steps.append(Step(what, result, time.monotonic() - began, ok))
            if not ok:
                break
    return steps


async def _progress(robot: Robot, label: str, live: Live, model: MapModel) -> None:
    stream = robot.statuses()
    try:
        async for status in stream:
            model.update("robot", status)
            line = Text(f"{label}\n  {status_line(status)}")
            live.update(Group(line, map_panel(model, DEMO_MAP_ROWS)))
    finally:
        await aclose(stream)


def _summary(steps: list[Step], total: float, url: str) -> Table:
    table = Table(title=f"galileo demo · {url}", caption=f"total {total:.1f} s")
    table.add_column("#", justify="right")
    table.add_column("step")
    table.add_column("result")
    table.add_column("time", justify="right")
    for number, step in enumerate(steps, 1):
        mark = "[green]✔[/]" if step.ok else "[red]✘[/]"
        table.add_row(str(number), step.what, f"{mark} {step.result}", f"{step.seconds:.1f} s")
    return table


def demo(
    ctx: typer.Context,
    speed: Annotated[
        float,
        typer.Option(
            min=0.5, max=100, help="Simulator time scale (a --port sim:// URL with speed= wins)."
        ),
    ] = DEMO_SPEED,
) -> None:
    """A scripted tour against the embedded simulator, with a summary table at the end."""
    settings = settings_of(ctx)
    if not is_sim(checked_port(settings)):
        fail("the demo drives the robot around, so it only runs on sim:// URLs", ExitCode.USAGE)
    url = with_query(settings.url, speed=f"{speed:g}")

    async def main() -> int:
        from ..robot import connect

        began = time.monotonic()
        show = err_console().is_terminal
        async with (
            connect(url, **settings.connect_options()) as robot,
            stop_on_interrupt(robot),
        ):
            steps = await tour(robot, show=show, model=known_targets([url], None))
        out_console().print(_summary(steps, time.monotonic() - began, url))
        return 0 if all(step.ok for step in steps) else int(ExitCode.ERROR)

    run(settings, main)
