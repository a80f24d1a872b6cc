"""``galileo foxglove``: a Foxglove live view of one robot, or of every robot of a fleet file.

Ctrl-C, SIGTERM and SIGHUP close the server and the robots' connections and exit 0, as
`galileo sim` does; like `galileo monitor`, the command sends nothing to a robot on its way
out (a goal started from Foxglove keeps running: stop it with its stop service, or
`galileo stop`).
"""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import AsyncIterator
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import anyio
import typer

from ..errors import GalileoError, InvalidArgument
from ..fleet.file import FleetSpec, load_fleet_file
from .fleet_cmd import served_options
from .metrics_opt import MetricsAddress, MetricsOption, metrics_address, metrics_served
from .runner import ExitCode, checked_port, err_console, fail, run, run_robot, settings_of
from .signals import stop_requested
from .watch import TargetsOption, map_model

if TYPE_CHECKING:
    from ..fleet.fleet import Fleet
    from ..foxglove import FoxgloveServer
    from ..robot import Robot

__all__ = ["HTTP_TARGETS_TIMEOUT", "foxglove"]

#: Seconds an http:// robot has to list its map's targets (the scene shows none without).
HTTP_TARGETS_TIMEOUT = 10.0

Targets = list[tuple[int, float, float]]

_NEEDS_SDK = (
    "galileo foxglove needs the Foxglove SDK (foxglove is not installed): "
    "pip install 'galileo-async[foxglove]'"
)


def foxglove(
    ctx: typer.Context,
    host: Annotated[
        str, typer.Option("--host", help="Address to listen on (0.0.0.0: every interface).")
    ] = "127.0.0.1",
    port: Annotated[
        int, typer.Option("--port", min=0, max=65535, help="WebSocket port viewers open.")
    ] = 8765,
    rate: Annotated[
        float,
        typer.Option("--rate", min=0.1, max=100, help="Pose and status messages a second."),
    ] = 10.0,
    fleet: Annotated[
        Path | None,
        typer.Option("--fleet", help="Every robot of this fleet file, /NAME/... each."),
    ] = None,
    name: Annotated[
        str, typer.Option("--name", help="The one robot's topic prefix (without --fleet).")
    ] = "robot",
    targets: TargetsOption = None,
    metrics: MetricsOption = None,
) -> None:
    """Serve a Foxglove live view (ws://HOST:PORT) of the robot, or every robot of --fleet."""
    settings = settings_of(ctx)
    address = metrics_address(metrics)
    try:
        import foxglove as _sdk  # noqa: F401
    except ImportError:
        fail(_NEEDS_SDK)
    fleet = fleet or settings.fleet
    if fleet is not None and settings.port_source in ("--port", "--robot"):
        fail(f"--fleet takes each robot's port from {fleet}: drop {settings.port_source}",
             ExitCode.USAGE)  # fmt: skip
    if "/" in name or not name:
        fail(f"--name must be a non-empty name without '/', got {name!r}", ExitCode.USAGE)
    spec: FleetSpec | None = None
    if fleet is not None:
        try:
            spec = load_fleet_file(fleet)
        except InvalidArgument as exc:
            fail(str(exc), ExitCode.USAGE)
        urls = dict(spec.ports)
        file = targets or spec.targets
    else:
        urls = {name: checked_port(settings) and settings.url}
        file = targets
    known = {robot: _targets_of(url, file) for robot, url in urls.items()}

    if spec is None:

        async def body(robot: Robot) -> int:
            async with _server(host, port, rate) as server:
                found = await _http_targets(robot, known[name])
                server.add_robot(name, robot, targets=found)
                with stop_requested() as stop:
                    await stop.wait()
            return 0

        run_robot(
            settings, body, navigation=None, interrupted=ExitCode.OK, long_running=True,
            metrics=address,
        )  # fmt: skip
    fleet_spec = spec

    async def main() -> int:
        async with _server(host, port, rate) as server:
            await _serve_fleet(server, fleet_spec, known, address)
        return 0

    run(settings, main, interrupted=ExitCode.OK)


@contextlib.asynccontextmanager
async def _server(host: str, port: int, rate: float) -> AsyncIterator[FoxgloveServer]:
    """The running server; its address said on stderr."""
    from ..foxglove import FoxgloveServer

    async with FoxgloveServer(host=host, port=port, rate=rate) as server:
        err_console().print(f"Foxglove live view on {server.url} · Ctrl-C stops", markup=False)
        yield server


def _targets_of(url: str, file: Path | None) -> Targets:
    """The targets known for ``url``: the simulator's map, the targets file's."""
    model = map_model([url], file)
    return [(t.target_id, t.x, t.y) for t in sorted(model.targets.values(), key=_id)]


def _id(target: object) -> int:
    return int(getattr(target, "target_id", 0))


async def _http_targets(robot: Robot, known: Targets) -> Targets:
    """``known``, or the saved targets of an http:// robot's current map when none are."""
    http = robot.http
    if known or http is None:
        return known
    try:
        points = await asyncio.wait_for(http.targets(), HTTP_TARGETS_TIMEOUT)
    except (GalileoError, asyncio.TimeoutError) as exc:
        err_console().print(f"no targets in the scene: {exc}", markup=False, style="yellow")
        return known
    return [(index, point.x, point.y) for index, point in enumerate(points)]


async def _serve_fleet(
    server: FoxgloveServer,
    spec: FleetSpec,
    known: dict[str, Targets],
    metrics: MetricsAddress | None,
) -> None:
    """Serve every robot of ``spec`` as it connects (now or later) until a stop signal."""
    connected: asyncio.Queue[tuple[str, Robot]] = asyncio.Queue()

    def on_connect(name: str, robot: Robot) -> None:
        connected.put_nowait((name, robot))

    async def add(name: str, robot: Robot) -> None:
        targets = await _http_targets(robot, known[name])
        if name not in server.robots:  # each robot once, under its fleet name
            server.add_robot(name, robot, targets=targets)

    async def attach() -> None:
        async with anyio.create_task_group() as adding:  # a slow robot delays no other
            while True:
                adding.start_soon(add, *await connected.get())

    fleet: Fleet
    # The metrics' address is bound before anything connects (metrics_served).
    async with metrics_served(metrics) as collector, spec.connect(**served_options(spec)) as fleet:
        if collector is not None:
            collector.add_fleet(fleet)
        fleet.add_connect_listener(on_connect, connected=True)
        try:
            with stop_requested() as stop:
                async with anyio.create_task_group() as group:
                    group.start_soon(attach)
                    await stop.wait()
                    group.cancel_scope.cancel()
        finally:
            fleet.remove_connect_listener(on_connect)
