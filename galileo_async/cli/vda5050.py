"""``galileo vda5050``: the robot as a VDA 5050 2.0 vehicle on an MQTT broker until Ctrl-C."""

from __future__ import annotations

from typing import TYPE_CHECKING, Annotated

import anyio
import typer

from .capture import stop_requested
from .runner import ExitCode, err_console, fail, run_robot, settings_of

if TYPE_CHECKING:
    from ..robot import Robot

__all__ = ["vda5050"]


def vda5050(
    ctx: typer.Context,
    broker: Annotated[
        str,
        typer.Option(help="MQTT broker: mqtt://[user:password@]host[:port] or mqtts://… (TLS)."),
    ],
    manufacturer: Annotated[str, typer.Option(help="The vehicle's manufacturer (topic level).")],
    serial_number: Annotated[
        str, typer.Option("--serial-number", help="The vehicle's serial number (topic level).")
    ],
    interface_name: Annotated[
        str, typer.Option("--interface-name", help="First topic level.")
    ] = "uagv",
    map_id: Annotated[str, typer.Option("--map-id", help="mapId of positions and orders.")] = (
        "map"
    ),
    start_navigation: Annotated[
        bool, typer.Option("--start-navigation", help="Open navigation at start.")
    ] = False,
    visualization_rate: Annotated[
        float, typer.Option("--visualization-rate", help="visualization messages/s (0..30).")
    ] = 10.0,
    ca_file: Annotated[
        str | None, typer.Option("--ca-file", help="CA certificate for mqtts:// (PEM).")
    ] = None,
) -> None:
    """Be a VDA 5050 2.0 vehicle: orders and instant actions from a master control over MQTT."""
    settings = settings_of(ctx)
    try:
        from ..vda5050 import Vehicle, VehicleConfig
    except ImportError:  # pragma: no cover - depends on the installed extras
        fail("the vda5050 command needs the extra: pip install 'galileo-async[vda5050]'")
    from ..errors import InvalidArgument

    try:
        config = VehicleConfig(
            broker=broker, manufacturer=manufacturer, serial_number=serial_number,
            interface_name=interface_name, map_id=map_id, start_navigation=start_navigation,
            visualization_rate=visualization_rate, tls_ca_file=ca_file,
        )  # fmt: skip
    except InvalidArgument as exc:
        fail(str(exc), ExitCode.USAGE)

    async def body(robot: Robot) -> int:
        vehicle = Vehicle(robot, config)
        err_console().print(
            f"VDA 5050 vehicle {config.topic('')}… on {broker} · Ctrl-C stops", markup=False
        )
        async with anyio.create_task_group() as group:
            group.start_soon(vehicle.run)
            with stop_requested() as stop:
                await stop.wait()
            group.cancel_scope.cancel()
        return 0

    run_robot(settings, body, long_running=True, interrupted=ExitCode.OK)
