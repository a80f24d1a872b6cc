"""``galileo vda5050``: the robot as a VDA 5050 2.0/2.1 vehicle on an MQTT broker until stopped.

Ctrl-C, SIGTERM (``systemctl stop``) and SIGHUP stop it cleanly: the order cancelled, the
robot stopped, a last state, OFFLINE, exit 0 (docs/cli.md, "Signals").
"""

from __future__ import annotations

import contextlib
import logging
import os
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import anyio
import typer

from .metrics_opt import MetricsOption, metrics_address
from .runner import ExitCode, err_console, fail, run_robot, settings_of
from .signals import stop_requested, stop_signal

if TYPE_CHECKING:
    from ..robot import Robot
    from ..vda5050 import Vehicle

__all__ = ["PASSWORD_ENV", "vda5050"]

#: The environment variable that holds the broker password (kept out of the process list).
PASSWORD_ENV = "GALILEO_MQTT_PASSWORD"


def _password(password_file: Path | None) -> str | None:
    """The broker password: --password-file, else GALILEO_MQTT_PASSWORD; empty is refused."""
    if password_file is not None:
        try:
            text = password_file.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            fail(f"cannot read --password-file {password_file}: {exc}", ExitCode.USAGE)
        password = text.rstrip("\r\n")  # the newlines an editor or `echo` adds
        if not password:
            fail(f"--password-file {password_file} is empty", ExitCode.USAGE)
        return password
    from_environment = os.environ.get(PASSWORD_ENV)
    if from_environment == "":
        fail(f"{PASSWORD_ENV} is set but empty", ExitCode.USAGE)
    return from_environment


#: The session's log line for a failed connect (it ends with "; retry in N s").
_CANNOT_CONNECT = "cannot connect to the broker"


def _shown(record: logging.LogRecord) -> bool:
    """Warnings, and every failed connect (a repeated reason is only INFO in the session)."""
    from ..vda5050.session import MQTT_LOGGER

    # The MQTT client repeats its socket errors on every retry; the session's line
    # carries the reason (and -v shows them all).
    if record.name.startswith(MQTT_LOGGER):
        return False
    return record.levelno >= logging.WARNING or _CANNOT_CONNECT in record.getMessage()


class _RetryFormatter(logging.Formatter):
    """A failed connect as "retrying: … (next try at HH:MM:SS)"; other records as they are."""

    def format(self, record: logging.LogRecord) -> str:
        message = record.getMessage()
        if _CANNOT_CONNECT not in message:
            return super().format(record)
        delay = record.args[-1] if isinstance(record.args, tuple) and record.args else None
        when = ""
        if isinstance(delay, float | int):
            when = time.strftime(" (next try at %H:%M:%S)", time.localtime(time.time() + delay))
        return f"retrying: {message}{when}"


async def _tell_links(vehicle: Vehicle, robot: Robot, shown: str) -> None:
    """One line on stderr per broker connection and per robot link outage and return."""
    from ..models import LinkState

    async def broker() -> None:
        again = ""
        while True:
            await vehicle.wait_online()
            err_console().print(f"connected to {shown}{again}: ONLINE", markup=False)
            again = " again"
            await vehicle.wait_offline()

    async with anyio.create_task_group() as group:
        group.start_soon(broker)
        down: LinkState | None = None
        async for state in robot.link_states():
            if state in (LinkState.LOST, LinkState.STALE) and down is None:
                down = state
                err_console().print(
                    f"robot link {state.name}: the vehicle reports robotLinkLost, orders "
                    "are refused", markup=False, style="yellow",
                )  # fmt: skip
            elif state is LinkState.UP and down is not None:
                down = None
                err_console().print("robot link UP again", markup=False)
        group.cancel_scope.cancel()


@contextlib.contextmanager
def _warnings_on_stderr(verbose: int) -> Iterator[None]:
    """Show the vehicle's warnings and its broker retries on stderr even without -v."""
    if verbose:  # -v already shows every log line
        yield
        return
    handler = logging.StreamHandler(sys.stderr)
    handler.setLevel(logging.INFO)
    handler.addFilter(_shown)
    handler.setFormatter(_RetryFormatter("%(levelname)s %(name)s: %(message)s"))
    logger = logging.getLogger("galileo_async.vda5050")
    level = logger.level
    if not logger.isEnabledFor(logging.INFO):
        logger.setLevel(logging.INFO)
    logger.addHandler(handler)
    try:
        yield
    finally:
        logger.removeHandler(handler)
        logger.setLevel(level)


def vda5050(
    ctx: typer.Context,
    broker: Annotated[
        list[str],
        typer.Option(
            help="MQTT broker: mqtt://[user@]host[:port] or mqtts://… (TLS); repeat it for "
            "brokers to move to when one is lost (round robin). The password: "
            f"{PASSWORD_ENV} or --password-file (in the URL, other users can read it)."
        ),
    ],
    manufacturer: Annotated[str, typer.Option(help="The vehicle's manufacturer (topic level).")],
    serial_number: Annotated[
        str | None,
        typer.Option(
            "--serial-number", help="The vehicle's serial number (topic level); not with --fleet."
        ),
    ] = None,
    fleet: Annotated[
        Path | None,
        typer.Option(
            "--fleet", help="Every robot of this fleet file as its own vehicle (docs/vda5050.md)."
        ),
    ] = None,
    shard: Annotated[
        str | None,
        typer.Option("--shard", help="With --fleet: only shard K of N of its robots (K/N)."),
    ] = None,
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
    tls_cert: Annotated[
        str | None,
        typer.Option("--tls-cert", help="Client certificate for mqtts:// (PEM; mutual TLS)."),
    ] = None,
    tls_key: Annotated[
        str | None,
        typer.Option("--tls-key", help="The client certificate's key (PEM, unencrypted)."),
    ] = None,
    password_file: Annotated[
        Path | None,
        typer.Option(
            "--password-file", help=f"File holding the broker password (else {PASSWORD_ENV})."
        ),
    ] = None,
    vda_version: Annotated[
        str, typer.Option("--vda-version", help="VDA 5050 version spoken: 2.0 or 2.1.")
    ] = "2.0",
    broker_loss_stop: Annotated[
        float | None,
        typer.Option(
            "--broker-loss-stop",
            help="Cancel a running order after this many seconds without the broker "
            "(default: the order goes on, VDA 5050 §6.2).",
        ),
    ] = None,
    width: Annotated[float, typer.Option(help="Factsheet: the robot's width, m.")] = 0.0,
    length: Annotated[float, typer.Option(help="Factsheet: the robot's length, m.")] = 0.0,
    height: Annotated[float, typer.Option(help="Factsheet: the robot's height, m.")] = 0.0,
    metrics: MetricsOption = None,
) -> None:
    """Be a VDA 5050 2.0 or 2.1 vehicle: orders and instant actions from a master over MQTT."""
    serve = metrics_address(metrics)
    settings = settings_of(ctx)
    try:
        from ..vda5050 import Vehicle, VehicleConfig, parse_broker_url, redact_url
        from ..vda5050.session import CONNECT_TIMEOUT, tls_context
    except ImportError:  # pragma: no cover - depends on the installed extras
        fail("the vda5050 command needs the extra: pip install 'galileo-async[vda5050]'")
    from ..errors import DuplicateVehicle, InvalidArgument

    if fleet is None and serial_number is None and settings.fleet is not None:
        fleet = settings.fleet  # galileo --fleet FILE vda5050
    if (fleet is None) == (serial_number is None):
        fail("give --serial-number (one robot) or --fleet FILE (every robot of it)", ExitCode.USAGE)
    if shard is not None and fleet is None:
        fail("--shard splits a fleet: give --fleet FILE", ExitCode.USAGE)
    try:
        in_url = any(parse_broker_url(url).password is not None for url in broker)
        password = _password(password_file)
        common: dict[str, Any] = dict(
            broker=broker[0], fallback_brokers=tuple(broker[1:]), manufacturer=manufacturer,
            interface_name=interface_name, map_id=map_id, start_navigation=start_navigation,
            visualization_rate=visualization_rate, tls_ca_file=ca_file, tls_cert_file=tls_cert,
            tls_key_file=tls_key, password=password, vda_version=vda_version,
            broker_loss_stop_delay=broker_loss_stop, width=width, length=length,
            height_max=height,
        )  # fmt: skip
        # With --fleet: the options shared by every vehicle, checked once before any opens.
        config = VehicleConfig(serial_number=serial_number or "fleet", **common)
        tls_context(config)  # unreadable certificate files: a usage error before connecting
    except InvalidArgument as exc:
        fail(str(exc), ExitCode.USAGE)
    if in_url:
        err_console().print(
            f"warning: the --broker URL holds the password, which other users of this machine "
            f"can read (process list, shell history); use {PASSWORD_ENV} or --password-file",
            markup=False, style="yellow",
        )  # fmt: skip
    shown = ", ".join(redact_url(url) for url in broker)
    if fleet is not None:
        from .vda5050_fleet import run_fleet

        with _warnings_on_stderr(settings.verbose):
            run_fleet(settings, fleet, shard, common, metrics=serve)

    async def body(robot: Robot) -> int:
        vehicle = Vehicle(robot, config)
        err_console().print(
            f"VDA 5050 vehicle {config.topic('')}… on {shown} · Ctrl-C stops", markup=False
        )
        err_console().print(
            f"connecting to {shown} (each try gives up after {CONNECT_TIMEOUT:g} s; "
            "failed tries are retried with back-off)…",
            markup=False,
            style="dim",
        )
        duplicate: list[DuplicateVehicle] = []

        async def run_vehicle(group: anyio.abc.TaskGroup) -> None:
            try:
                await vehicle.run()
            except DuplicateVehicle as exc:  # exit code DUPLICATE_VEHICLE (docs/cli.md)
                duplicate.append(exc)
                group.cancel_scope.cancel()

        with _warnings_on_stderr(settings.verbose):
            async with anyio.create_task_group() as group:
                group.start_soon(run_vehicle, group)
                group.start_soon(_tell_links, vehicle, robot, shown)
                with stop_requested() as stop:
                    await stop.wait()
                received = stop_signal()
                name = "a stop request" if received is None else received.name
                # Still on the broker: the last state says what the stop cut short.
                shutdown = await vehicle.shut_down(f"galileo vda5050 stopped by {name}")
                group.cancel_scope.cancel()
        if duplicate:
            raise duplicate[0]
        offline = (
            "OFFLINE published"
            if vehicle.session.offline_published
            else "OFFLINE not published (the broker was away)"
        )
        err_console().print(f"stopped by {name}: {shutdown}; {offline}", markup=False)
        return 0

    run_robot(settings, body, long_running=True, interrupted=ExitCode.OK, metrics=serve)
