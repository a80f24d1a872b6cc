"""``galileo --fleet FILE fleet …``: many robots from one fleet file (status, monitor)."""

from __future__ import annotations

import json
from typing import TYPE_CHECKING, Annotated

import anyio
import typer
from rich.live import Live

from ..errors import InvalidArgument
from ..fleet.file import FleetSpec, load_fleet_file
from ..fleet.fleet import RobotState
from .fleet_view import SORT_KEYS, FleetView
from .goals import aclose
from .map_render import save_svg
from .monitor_screen import keys_pressed
from .render import event_text
from .runner import ExitCode, fail, out_console, run, settings_of, timestamp
from .watch import SvgOption, TargetsOption, map_model

if TYPE_CHECKING:
    from ..fleet.fleet import Fleet

__all__ = ["FLEET_REFRESH", "fleet_app"]

fleet_app = typer.Typer(help="Many robots at once, from the fleet file given with --fleet.")

#: Screen refreshes per second of the fleet monitor (its data keeps flowing in between).
FLEET_REFRESH = 4.0

SortOption = Annotated[str, typer.Option("--sort", help=f"Sort rows by: {', '.join(SORT_KEYS)}.")]
MatchOption = Annotated[
    str, typer.Option("--match", help="Only robots whose name contains this text.")
]
StateOption = Annotated[
    list[str] | None,
    typer.Option("--state", help="Only robots in this link state (repeatable): "
                 + ", ".join(state.value for state in RobotState)),
]  # fmt: skip
RowsOption = Annotated[int, typer.Option("--rows", min=1, help="Table rows shown at most.")]


def _spec(ctx: typer.Context) -> FleetSpec:
    path = settings_of(ctx).fleet
    if path is None:
        fail("fleet commands need a fleet file: galileo --fleet fleet.toml fleet …", ExitCode.USAGE)
    try:
        return load_fleet_file(path)
    except InvalidArgument as exc:
        fail(str(exc), ExitCode.USAGE)


def _view_options(sort: str, states: list[str] | None) -> set[RobotState] | None:
    if sort not in SORT_KEYS:
        fail(f"--sort must be one of {', '.join(SORT_KEYS)}, got {sort!r}", ExitCode.USAGE)
    try:
        return {RobotState(state) for state in states} if states else None
    except ValueError as exc:
        fail(f"--state: {exc}", ExitCode.USAGE)


@fleet_app.command("status")
def status(
    ctx: typer.Context,
    sort: SortOption = "name",
    match: MatchOption = "",
    state: StateOption = None,
    rows: RowsOption = 1000,
    json_output: Annotated[bool, typer.Option("--json", help="JSON lines, one per robot.")] = False,
) -> None:
    """One table of every robot (JSON lines with --json), once every robot was tried.

    Exits 7 (connection) unless every robot is up.
    """
    settings, spec = settings_of(ctx), _spec(ctx)
    settings.json = settings.json or json_output
    states = _view_options(sort, state)

    async def main() -> int:
        async with spec.connect() as fleet:
            view = FleetView(fleet, map_model([], None), sort=sort, match=match, states=states,
                             limit=rows)  # fmt: skip
            view.latest = {name: fleet[name].status for name in fleet if _has_status(fleet, name)}
            console = out_console()
            view.width = console.width
            if settings.json:
                for row in view.rows()[:rows]:
                    line = {"time": timestamp()} | row.as_dict()
                    console.print(json.dumps(line), markup=False, soft_wrap=True)
            else:
                console.print(view.table())
            up = all(fleet.state(name) is RobotState.UP for name in fleet)
        return ExitCode.OK if up else ExitCode.CONNECTION

    run(settings, main)


def _has_status(fleet: Fleet, name: str) -> bool:
    robot = fleet.get(name)
    return robot is not None and robot.status is not None


@fleet_app.command("monitor")
def monitor(
    ctx: typer.Context,
    duration: Annotated[
        float | None, typer.Option(min=0.1, help="Stop after seconds (default: Ctrl-C).")
    ] = None,
    sort: SortOption = "name",
    match: MatchOption = "",
    state: StateOption = None,
    rows: RowsOption = 20,
    targets: TargetsOption = None,
    svg: SvgOption = None,
) -> None:
    """Live: a row per robot, a summary line and the map of every robot (key q quits)."""
    settings, spec = settings_of(ctx), _spec(ctx)
    states = _view_options(sort, state)
    model = map_model(list(spec.ports.values()), targets or spec.targets)

    async def main() -> int:
        async with spec.connect() as fleet:
            view = FleetView(fleet, model, sort=sort, match=match, states=states, limit=rows)
            try:
                await _watch(fleet, view, duration)
            finally:
                if svg is not None:
                    save_svg(view.screen(), svg, title="galileo fleet monitor")
        return 0

    run(settings, main, interrupted=ExitCode.OK)


async def _watch(fleet: Fleet, view: FleetView, duration: float | None) -> None:
    """Feed ``view`` from the merged streams; redraw FLEET_REFRESH times a second."""

    async def follow_statuses() -> None:
        stream = fleet.statuses()
        try:
            async for name, current in stream:
                view.latest[name] = view.changed[name] = current
        finally:
            await aclose(stream)

    async def follow_events() -> None:
        stream = fleet.events()
        try:
            async for name, event in stream:
                view.events[name] = event_text(event)
        finally:
            await aclose(stream)

    console = out_console()

    def fit() -> None:
        view.width = console.width
        view.height = console.size.height if console.is_terminal else None

    fit()
    async with anyio.create_task_group() as group:
        group.start_soon(follow_statuses)
        group.start_soon(follow_events)
        with keys_pressed(view.press) as typed:
            view.keys_hint = "q quit" if typed else ""
            with Live(view.screen(), console=console, auto_refresh=False) as live:
                with anyio.move_on_after(duration if duration is not None else float("inf")):
                    while not view.quit:
                        await anyio.sleep(1 / FLEET_REFRESH)
                        fit()
                        live.update(view.screen(), refresh=True)
        group.cancel_scope.cancel()
