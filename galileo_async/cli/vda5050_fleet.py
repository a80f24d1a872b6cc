"""``galileo vda5050 --fleet FILE [--shard K/N]``: every robot of a fleet file as its own vehicle.

Ctrl-C, SIGTERM and SIGHUP shut every vehicle down at once (as one vehicle's stop does:
its order cancelled, the robot stopped, a last state, OFFLINE), then exit 0.
"""

from __future__ import annotations

from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING, Any, NoReturn

import anyio

from ..errors import InvalidArgument
from ..fleet.file import FleetSpec, load_fleet_file
from ..fleet.shards import parse_shard
from ..links import link_kind
from .metrics_opt import MetricsAddress, follow_robots, metrics_served
from .runner import ExitCode, Settings, err_console, fail, run
from .signals import stop_requested, stop_signal

if TYPE_CHECKING:
    from ..robot import Robot
    from ..vda5050.fleet import FleetVehicle, VehicleFleet

__all__ = ["fleet_vehicles", "run_fleet"]


def _options(spec: FleetSpec, name: str) -> dict[str, Any]:
    """Robot ``name``'s connect() options: the file's, as a long-running command needs them."""
    port = spec.ports[name]
    options = {**spec.defaults, **spec.robot_options.get(name, {})}
    kind = link_kind(port)
    if kind in ("serial", "udp"):  # stop/cancel/pause from other terminals
        options.setdefault("control_socket", True)
    if kind == "sim":  # its map is known: orders by target number work
        from ..sim import parse_sim_url

        options.setdefault("map_targets", len(parse_sim_url(port).targets))
    return options


def fleet_vehicles(spec: FleetSpec, common: dict[str, Any]) -> dict[str, FleetVehicle]:
    """A FleetVehicle per robot of ``spec``: ``common`` VehicleConfig fields, its identity.

    InvalidArgument naming the robot whose configuration is wrong.
    """
    from ..robot import connect
    from ..vda5050 import VehicleConfig
    from ..vda5050.fleet import FleetVehicle

    result: dict[str, FleetVehicle] = {}
    for name, port in spec.ports.items():
        identity = {
            "manufacturer": spec.manufacturer(name, common["manufacturer"]),
            "serial_number": spec.serial_number(name),
        }
        try:
            config = VehicleConfig(**{**common, **identity})
        except InvalidArgument as exc:
            raise InvalidArgument(f"robot {name!r}: {exc}") from None
        result[name] = FleetVehicle(partial(connect, port, **_options(spec, name)), config)
    return result


def run_fleet(
    settings: Settings,
    path: Path,
    shard_text: str | None,
    common: dict[str, Any],
    *,
    metrics: MetricsAddress | None = None,
) -> NoReturn:
    """Run the robots of the fleet file ``path`` (of shard ``shard_text``) as vehicles; exit.

    ``metrics``: serve Prometheus metrics of every connected robot there (metrics_opt.py).
    """
    from ..vda5050 import redact_url
    from ..vda5050.fleet import VehicleFleet

    if settings.port_source in ("--port", "--robot"):
        fail(
            f"--fleet takes each robot's port from {path}: drop {settings.port_source}",
            ExitCode.USAGE,
        )
    try:
        spec = load_fleet_file(path)
        shard = None if shard_text is None else parse_shard(shard_text)
        if shard is not None:
            spec = spec.only(shard.select(spec.ports))
        robots = fleet_vehicles(spec, common) if spec.ports else {}
        fleet = VehicleFleet(robots) if robots else None
    except InvalidArgument as exc:
        fail(str(exc), ExitCode.USAGE)
    part = "" if shard is None else f" (shard {shard})"
    if fleet is None:
        err_console().print(f"no robot of {path} is in shard {shard}: nothing to run", markup=False)
        raise SystemExit(0)
    brokers = [common["broker"], *common["fallback_brokers"]]
    shown = ", ".join(redact_url(url) for url in brokers)

    async def main() -> int:
        err_console().print(
            f"VDA 5050 fleet: {len(robots)} vehicles of {path}{part} on {shown} · Ctrl-C stops",
            markup=False,
        )
        async with metrics_served(metrics) as served, anyio.create_task_group() as group:
            group.start_soon(fleet.run)
            if served is not None:
                group.start_soon(follow_robots, served, partial(_connected, fleet))
            with stop_requested() as stop:
                await stop.wait()
            received = stop_signal()
            name = "a stop request" if received is None else received.name
            # Still on the broker: each last state says what the stop cut short.
            reports = await fleet.shut_down(f"galileo vda5050 stopped by {name}")
            group.cancel_scope.cancel()
        vehicles = fleet.vehicles
        offline = sum(vehicle.session.offline_published for vehicle in vehicles.values())
        for robot, report in reports.items():
            if report.problems:
                err_console().print(f"{robot}: {report}", markup=False, style="yellow")
        err_console().print(
            f"stopped by {name}: {len(reports)} of {len(robots)} vehicles shut down; "
            f"OFFLINE published by {offline}",
            markup=False,
        )
        return 0

    run(settings, main, interrupted=ExitCode.OK)


def _connected(fleet: VehicleFleet) -> dict[str, Robot]:
    """The robots of ``fleet``'s vehicles that run now, by name."""
    return {
        name: vehicle.robot
        for name, vehicle in fleet.vehicles.items()
        if not fleet.ended(name) and not vehicle.robot.closed
    }
