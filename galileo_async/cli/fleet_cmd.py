"""``galileo --fleet FILE fleet …``: many robots from one fleet file (status, monitor, stop)."""

from __future__ import annotations

import dataclasses
import json
from typing import TYPE_CHECKING, Annotated, Any

import anyio
import typer
from rich.live import Live

from .._checks import hide_secrets
from ..errors import InvalidArgument, NotReady, PortBusy
from ..fleet.file import FleetSpec, load_fleet_file
from ..models import LinkState
from ..robot.stopping import DEFAULT_STOP_TIMEOUT
from .fleet_view import SORT_KEYS, FleetRow, FleetView
from .goals import aclose
from .map_render import save_svg
from .metrics_opt import MetricsOption, metrics_address, metrics_served
from .monitor_screen import keys_pressed
from .render import event_text, status_record
from .runner import ExitCode, fail, out_console, run, settings_of, timestamp
from .stopping import BrakeOption, Outcome, StopTimeout, error_outcome, gather_owners
from .watch import SvgOption, TargetsOption, map_model

if TYPE_CHECKING:
    from ..fleet.fleet import Fleet
    from ..models import GalileoStatus

__all__ = ["FLEET_REFRESH", "fleet_app", "fleet_spec", "served_options"]

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
                 + ", ".join(state.value for state in LinkState)),
]  # fmt: skip
RowsOption = Annotated[int, typer.Option("--rows", min=1, help="Table rows shown at most.")]


def fleet_spec(ctx: typer.Context) -> FleetSpec:
    """The fleet file given with --fleet, loaded; a missing or bad one exits 2."""
    path = settings_of(ctx).fleet
    if path is None:
        fail("fleet commands need a fleet file: galileo --fleet fleet.toml fleet …", ExitCode.USAGE)
    try:
        return load_fleet_file(path)
    except InvalidArgument as exc:
        fail(str(exc), ExitCode.USAGE)


def served_options(spec: FleetSpec) -> dict[str, Any]:
    """Serve each robot's control socket (serial and udp:// ports), unless the file says."""
    return {} if "control_socket" in spec.defaults else {"control_socket": True}


def _view_options(sort: str, states: list[str] | None) -> set[LinkState] | None:
    if sort not in SORT_KEYS:
        fail(f"--sort must be one of {', '.join(SORT_KEYS)}, got {sort!r}", ExitCode.USAGE)
    try:
        return {LinkState(state) for state in states} if states else None
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
    settings, spec = settings_of(ctx), fleet_spec(ctx)
    settings.json = settings.json or json_output
    states = _view_options(sort, state)

    async def main() -> int:
        async with spec.connect(**served_options(spec)) as fleet:
            view = FleetView(fleet, map_model([], None), sort=sort, match=match, states=states,
                             limit=rows)  # fmt: skip
            view.latest = {name: fleet[name].status for name in fleet if _has_status(fleet, name)}
            console = out_console()
            view.width = console.width
            if settings.json:
                for row in view.rows()[:rows]:
                    line = _status_line(fleet, row.name, view.latest.get(row.name), row)
                    console.print(json.dumps(line), markup=False, soft_wrap=True)
            else:
                console.print(view.table())
            up = all(fleet.state(name) is LinkState.UP for name in fleet)
        return ExitCode.OK if up else ExitCode.CONNECTION

    run(settings, main)


def _status_line(
    fleet: Fleet, name: str, latest: GalileoStatus | None, row: FleetRow
) -> dict[str, Any]:
    """A robot's JSON status line: a status line's shape (render.status_record) with its
    name, its state (also before it connected) and its last event or connect error."""
    robot = fleet.get(name)
    return {
        "port": hide_secrets(fleet.url(name)),
        "time": timestamp(),
        **status_record(latest, None if robot is None else robot.link),
        "name": name,
        "state": row.state.value,
        "last_event": row.last_event or None,
    }


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
    metrics: MetricsOption = None,
) -> None:
    """Live: a row per robot, a summary line and the map of every robot (key q quits)."""
    serve = metrics_address(metrics)
    settings, spec = settings_of(ctx), fleet_spec(ctx)
    states = _view_options(sort, state)
    model = map_model(list(spec.ports.values()), targets or spec.targets)

    async def main() -> int:
        async with metrics_served(serve) as served, spec.connect(**served_options(spec)) as fleet:
            if served is not None:
                served.add_fleet(fleet)
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


@fleet_app.command("stop")
def stop(
    ctx: typer.Context,
    brake: BrakeOption = 100,
    timeout: StopTimeout = DEFAULT_STOP_TIMEOUT,
    json_output: Annotated[bool, typer.Option("--json", help="JSON lines, one per robot.")] = False,
) -> None:
    """Stop every robot of the fleet at once, as `galileo stop` stops one; a line per robot.

    A robot whose port another galileo process has open is stopped through that process.
    Exits 0 once every robot confirmed, 7 when one could not be reached, else 6 when one
    did not confirm in time.
    """
    settings, spec = settings_of(ctx), fleet_spec(ctx)
    settings.json = settings.json or json_output
    request: dict[str, Any] = {"brake": brake, "timeout": timeout}

    async def main() -> int:
        outcomes = await _stop_fleet(spec, request)
        console = out_console()
        for name, outcome in outcomes.items():
            if settings.json:
                line = {"time": timestamp(), "name": name, "port": spec.ports[name]}
                console.print(json.dumps(line | outcome.data()), markup=False, soft_wrap=True)
            else:
                console.print(f"{name}: {_said(outcome)}", markup=False, soft_wrap=True)
        return _fleet_code([outcome.code for outcome in outcomes.values()])

    run(settings, main)


async def _stop_fleet(spec: FleetSpec, request: dict[str, Any]) -> dict[str, Outcome]:
    """Every robot's Outcome: through its port's owner, else on the fleet's own connection."""
    asked = await gather_owners(spec.ports, "stop", request)
    outcomes = {name: found for name, found in asked.items() if isinstance(found, Outcome)}
    rest = [name for name in spec.ports if name not in outcomes]
    if rest:
        subset = dataclasses.replace(
            spec,
            ports={name: spec.ports[name] for name in rest},
            robot_options={n: o for n, o in spec.robot_options.items() if n in rest},
        )
        async with subset.connect(**served_options(subset)) as fleet:
            results = await fleet.stop(request["brake"], timeout=request["timeout"])
            busy = [name for name in rest if isinstance(fleet.error(name), PortBusy)]
            again = await gather_owners({name: spec.ports[name] for name in busy}, "stop", request)
            for name in rest:
                result, owner = results[name], again.get(name)
                if isinstance(owner, Outcome):  # its owner started while we connected
                    outcomes[name] = owner
                elif result.ok:
                    report = result.value
                    stopped = [] if report is None else list(report.stopped)
                    outcomes[name] = Outcome({"done": str(report), "stopped": stopped})
                elif fleet.get(name) is None:  # never connected: why, not "not connected"
                    why = fleet.error(name) or result.error or NotReady("not connected", None)
                    outcomes[name] = error_outcome(why, ExitCode.CONNECTION)
                else:
                    outcomes[name] = error_outcome(result.error or NotReady("failed", None))
    return {name: outcomes[name] for name in spec.ports}


def _said(outcome: Outcome) -> str:
    if outcome.error is None:
        return outcome.text()
    how = {ExitCode.CONNECTION: "not reached", ExitCode.TIMEOUT: "not confirmed"}
    return f"{how.get(outcome.code, 'failed')}: {outcome.text()}"


def _fleet_code(codes: list[ExitCode]) -> int:
    """0 when every robot stopped; 7 when one was not reached, else 6 when one did not confirm."""
    failed = [code for code in codes if code != ExitCode.OK]
    for code in (ExitCode.CONNECTION, ExitCode.TIMEOUT):
        if code in failed:
            return int(code)
    return int(failed[0]) if failed else 0
