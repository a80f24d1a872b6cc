"""The ``galileo`` Typer application: global options and the command table."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from .. import __version__
from ..errors import InvalidArgument
from ..links import URL_SCHEMES, url_forms
from ..options import MAX_TARGET_ID, STREAM_LAYOUTS
from . import (
    capture,
    demo,
    fleet_cmd,
    foxglove_cmd,
    mcap_cmd,
    mission,
    mission_run,
    mission_schedule,
    ops,
    serve,
    stopping,
    teleop,
    vda5050,
    watch,
)
from .profiles import ROBOT_ENV, find_profile, profile_names
from .runner import (
    DEFAULT_PORT,
    PORT_ENV,
    ExitCode,
    PortSource,
    Settings,
    fail,
    resolve_port,
    setup_logging,
)
from .usage import NumberArguments, UsageErrorsAsJson

__all__ = ["app", "main"]

app = typer.Typer(
    name="galileo",
    cls=UsageErrorsAsJson,  # usage errors are JSON when the command line has --json
    help=(
        "Drive and watch a Galileo navigation robot on a serial device or "
        f"{', '.join(f'{scheme}://' for scheme in URL_SCHEMES)}; without --port on "
        f"{DEFAULT_PORT}, the built-in simulator."
    ),
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    rich_markup_mode=None,
)


#: Layouts of the serial status stream (docs/protocol.md §1) that --layout accepts: the
#: layout option's (galileo_async.options).
_LAYOUTS = STREAM_LAYOUTS


def _version(value: bool) -> None:
    if value:
        typer.echo(f"galileo {__version__}")
        raise typer.Exit()


def _complete_robot(ctx: typer.Context, incomplete: str) -> list[str]:
    fleet = ctx.params.get("fleet")
    names = profile_names(fleet if isinstance(fleet, Path) else None)
    return [name for name in names if name.startswith(incomplete)]


@app.callback()
def options(
    ctx: typer.Context,
    port: Annotated[
        str | None,
        typer.Option(
            "--port",
            "-p",
            metavar="URL",
            envvar=PORT_ENV,
            show_envvar=True,
            help=(
                # Built at import: the schemes of installed plugins are not loaded for it.
                f"Where the robot is: {url_forms(plugins=False)}, or a scheme an installed "
                f"plugin adds. Default: {DEFAULT_PORT}, the built-in "
                "simulator (robot commands say so on stderr)."
            ),
        ),
    ] = None,
    robot: Annotated[
        str | None,
        typer.Option(
            "--robot",
            "-r",
            envvar=ROBOT_ENV,
            show_envvar=True,
            autocompletion=_complete_robot,
            help="A named robot (port and connect options) of the --fleet file or of "
            "$XDG_CONFIG_HOME/galileo/config.toml ([robots.NAME] port = …).",
        ),
    ] = None,
    layout: Annotated[
        str | None,
        typer.Option(help=f"Pin the status layout: {', '.join(_LAYOUTS)} (default auto)."),
    ] = None,
    map_targets: Annotated[
        int | None,
        typer.Option(
            "--map-targets",
            envvar="GALILEO_MAP_TARGETS",
            min=0,
            max=MAX_TARGET_ID,
            help="Number of targets in the robot's map (needed by goto-point; sim:// knows "
            "it, ros:// reads /galileo/goal_num).",
        ),
    ] = None,
    fleet: Annotated[
        Path | None,
        typer.Option(
            "--fleet",
            envvar="GALILEO_FLEET",
            help="Fleet file (TOML, [robots.NAME] port = …) for the fleet commands.",
        ),
    ] = None,
    verbose: Annotated[
        int, typer.Option("--verbose", "-v", count=True, help="-v debug logs, -vv raw frames.")
    ] = 0,
    json_output: Annotated[
        bool, typer.Option("--json", help="JSON output where the output is data.")
    ] = False,
    log_file: Annotated[
        Path | None,
        typer.Option("--log-file", help="Write debug logs (UTC timestamps) to this file."),
    ] = None,
    version: Annotated[
        bool | None,
        typer.Option("--version", callback=_version, is_eager=True, help="Show the version."),
    ] = None,
) -> None:
    """Drive and watch a Galileo navigation robot. Every command works on sim:// out of the box."""
    if layout is not None and layout not in _LAYOUTS:
        message = f"{layout!r} is not one of {', '.join(_LAYOUTS)}"
        raise typer.BadParameter(message, param_hint="--layout")
    source_name = getattr(ctx.get_parameter_source("port"), "name", None)
    from_environment = source_name == "ENVIRONMENT"
    extra: dict[str, object] = {}
    source: PortSource
    if robot is not None and _robot_wins(ctx, port, from_environment):
        try:
            profile = find_profile(robot, fleet)
        except InvalidArgument as exc:
            fail(str(exc), ExitCode.USAGE)
        port, extra = profile.port, dict(profile.options)
        robot_source = getattr(ctx.get_parameter_source("robot"), "name", None)
        source = "GALILEO_ROBOT" if robot_source == "ENVIRONMENT" else "--robot"
    else:
        port, source = resolve_port(port, from_environment=from_environment)
    ctx.obj = Settings(
        port=port,
        port_source=source,
        extra=extra,
        layout=layout,
        verbose=verbose,
        json=json_output,
        map_targets=map_targets,
        fleet=fleet,
    )
    setup_logging(verbose, log_file)


def _robot_wins(ctx: typer.Context, port: str | None, port_from_environment: bool) -> bool:
    """--robot over GALILEO_PORT, --port over GALILEO_ROBOT; the same level twice: an error."""
    if port is None:
        return True
    robot_from_environment = (
        getattr(ctx.get_parameter_source("robot"), "name", None) == "ENVIRONMENT"
    )
    if port_from_environment == robot_from_environment:
        both = f"{PORT_ENV} and {ROBOT_ENV}" if robot_from_environment else "--port and --robot"
        fail(f"{both} both name the robot: give one", ExitCode.USAGE)
    return port_from_environment


app.command("status")(watch.status)
app.command("monitor")(watch.monitor)
app.add_typer(ops.nav_app, name="nav")
# NumberArguments: "-2.5" is a number, "-1" gets the range error, "--timout" no such option.
app.command("goto", cls=NumberArguments)(ops.goto)
app.command("goto-point", cls=NumberArguments)(ops.goto_point)
app.command("stop")(stopping.stop)  # everything; nav/patrol/charge stop stop one service
app.command("pause")(stopping.pause)
_GROUPS = {
    None: app, "nav": ops.nav_app, "patrol": ops.patrol_app, "map": ops.map_app,
    "charge": ops.charge_app,
}  # fmt: skip
for _group, _name, _method, _done, _help in ops.SIMPLE_COMMANDS:
    _GROUPS[_group].command(_name, help=_help)(ops.simple_command(_method, _done, _help))
app.command("cancel")(stopping.cancel)
app.command("rotate", cls=NumberArguments)(ops.rotate)
app.command("teleop")(teleop.teleop)
app.add_typer(ops.patrol_app, name="patrol")
app.add_typer(ops.map_app, name="map")
app.add_typer(ops.charge_app, name="charge")
app.command("shutdown")(ops.shutdown)
app.command("send", cls=NumberArguments)(ops.send)
app.command("decode")(capture.decode)
app.command("record")(capture.record)
app.command("ports")(serve.ports)
app.command("discover")(serve.discover)
app.command("sim")(serve.sim)
app.command("replay")(serve.replay)
app.command("demo")(demo.demo)
# VDA 5050 (extra [vda5050]): the module imports aiomqtt only when the command runs.
app.command("vda5050")(vda5050.vda5050)
# Foxglove live view (extra [foxglove]): the module imports the SDK only when the command runs.
app.command("foxglove")(foxglove_cmd.foxglove)
app.add_typer(fleet_cmd.fleet_app, name="fleet")  # --fleet FILE fleet status | monitor
# Missions (extra [missions]): the module imports yaml only when a command runs.
app.add_typer(mission.mission_app, name="mission")
mission_run.register(mission.mission_app)
mission_schedule.register(mission.mission_app)
# `galileo --fleet F fleet mission run FILE`
mission_run.register_fleet(fleet_cmd.fleet_app)
fleet_cmd.fleet_app.command("record")(mcap_cmd.fleet_record)


def main() -> None:
    """Console-script entry point of ``galileo``."""
    app(prog_name="galileo")
