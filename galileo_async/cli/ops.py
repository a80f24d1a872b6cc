"""Commands that drive the robot: navigation, goals, patrol, mapping, charging, raw commands."""

from __future__ import annotations

import asyncio
import dataclasses
from collections.abc import Awaitable, Callable
from typing import TYPE_CHECKING, Annotated, Any

import typer

from ..errors import InvalidArgument, UnconfirmedOperation
from ..protocol import COMMAND_TYPES, Command, RawCommand, encode
from .goals import clear_goal_error, run_goal, with_progress
from .runner import (
    ExitCode,
    err_console,
    fail,
    out_console,
    print_json,
    run_robot,
    settings_of,
)

if TYPE_CHECKING:
    from ..robot import Robot

__all__ = [
    "CLI_ROTATE_TIMEOUT",
    "SIMPLE_COMMANDS",
    "charge_app",
    "goto",
    "goto_point",
    "map_app",
    "nav_app",
    "nav_start",
    "parse_command",
    "patrol_app",
    "rotate",
    "send",
    "shutdown",
    "simple_command",
    "start_navigation",
    "start_patrol",
]

StartNav = Annotated[
    bool | None,
    typer.Option(
        "--start-nav/--no-start-nav",
        help="Start navigation first when it is closed (default: only on sim://).",
        show_default=False,
    ),
]
GoalTimeout = Annotated[
    float, typer.Option("--timeout", "-t", min=0.1, help="Give up (and cancel) after seconds.")
]
JsonFlag = Annotated[bool, typer.Option("--json", help="Print the result as JSON.")]


nav_app = typer.Typer(help="Start or stop the navigation service.", no_args_is_help=True)
patrol_app = typer.Typer(help="Auto-patrol over every target.", no_args_is_help=True)
map_app = typer.Typer(help="Build, save and update the map.", no_args_is_help=True)
charge_app = typer.Typer(help="Docking and charging.", no_args_is_help=True)


def _simple(
    ctx: typer.Context,
    call: Callable[[Robot], Awaitable[object]],
    done: str,
    *,
    navigation: bool | None = False,
    moving: bool = False,
) -> None:
    settings = settings_of(ctx)
    label = ctx.command_path.removeprefix(ctx.find_root().info_name or "").strip()

    async def body(robot: Robot) -> int:
        await with_progress(robot, label, call(robot), show=not settings.json)
        if settings.json:
            print_json(settings, {"result": "ok", "done": done})
        else:
            out_console().print(done)
        return 0

    run_robot(settings, body, navigation=navigation, moving=moving)


# --- goals -------------------------------------------------------------------------------


def goto(
    ctx: typer.Context,
    target_id: Annotated[int, typer.Argument(min=0, max=255, help="Map target id.")],
    timeout: GoalTimeout = 300.0,
    start_nav: StartNav = None,
    json_output: JsonFlag = False,
) -> None:
    """Go to a map target with live progress; the exit code tells the result."""
    settings = settings_of(ctx)
    settings.json = settings.json or json_output

    async def body(robot: Robot) -> int:
        await clear_goal_error(robot)
        return await run_goal(
            settings,
            robot,
            f"goto {target_id}",
            lambda: robot.goto(target_id, timeout=timeout),
            target_id=target_id,
        )

    run_robot(settings, body, navigation=start_nav, moving=True)


def goto_point(
    ctx: typer.Context,
    x: Annotated[float, typer.Argument(help="Map x, metres.")],
    y: Annotated[float, typer.Argument(help="Map y, metres.")],
    timeout: GoalTimeout = 300.0,
    start_nav: StartNav = None,
    json_output: JsonFlag = False,
) -> None:
    """Go to map coordinates (a dynamic target) with live progress; exit code by result."""
    settings = settings_of(ctx)
    settings.json = settings.json or json_output

    async def body(robot: Robot) -> int:
        label = f"goto-point ({x:g}, {y:g})"
        # goto-point writes three commands: reset the dynamic targets, add one, go there.
        return await run_goal(
            settings, robot, label, lambda: robot.goto_point(x, y, timeout=timeout), goal_commands=3
        )

    run_robot(settings, body, navigation=start_nav, moving=True)


#: Default --timeout of ``galileo rotate``, shorter than Robot.rotate_to's ROTATE_TIMEOUT: a
#: half turn takes a few seconds, and many firmware versions drop 'a' silently
#: (docs/protocol.md §2.g), so do not keep the user waiting long.
CLI_ROTATE_TIMEOUT = 10.0


def rotate(
    ctx: typer.Context,
    degrees: Annotated[int, typer.Argument(min=-180, max=180, help="Heading, degrees.")],
    timeout: Annotated[
        float, typer.Option("--timeout", "-t", min=0.1, help="Give up after seconds.")
    ] = CLI_ROTATE_TIMEOUT,
    start_nav: StartNav = None,
) -> None:
    """Rotate to a heading (-180..180); many firmware versions ignore it (then: timeout)."""

    async def call(robot: Robot) -> None:
        err_console().print(
            f"rotate: waiting up to {timeout:g} s for angle_goal_status to show the turn done; "
            "many firmware versions ignore the rotate command 'a' (then: exit code 6)",
            markup=False,
            style="dim",
        )
        await robot.rotate_to(degrees, timeout=timeout)

    _simple(ctx, call, f"rotated to {degrees}°", navigation=start_nav, moving=True)


# --- navigation -----------------------------------------------------------------------------

#: Seconds ``nav start`` waits for nav_status to show a start before it sends it again.
START_RETRY = 3.0


@nav_app.command("start")
def nav_start(
    ctx: typer.Context,
    timeout: Annotated[
        float, typer.Option("--timeout", "-t", min=0.1, help="Give up after seconds.")
    ] = 60.0,
) -> None:
    """Start navigation; return once it is open and the visual system is initialised.

    The firmware ignores a start within 5-30 s of the previous one: a start that does not
    show within 3 s is said at once and sent again until it shows or --timeout ends.
    """

    async def call(robot: Robot) -> None:
        await start_navigation(robot, timeout, show=not settings_of(ctx).json)

    _simple(ctx, call, "navigation open, visual initialised")


async def start_navigation(robot: Robot, timeout: float, *, show: bool) -> None:
    """start_navigation, sent again every START_RETRY s while the firmware's lockout drops it."""
    loop = asyncio.get_running_loop()
    deadline = loop.time() + timeout
    while True:
        remaining = deadline - loop.time()
        try:
            await robot.start_navigation(timeout=max(0.1, min(START_RETRY, remaining)))
            return
        except UnconfirmedOperation:
            status = robot.status
            left = deadline - loop.time()
            if left <= 0:
                raise
            if show and (status is None or not status.navigating):
                err_console().print(
                    f"nav start: the robot ignored the start (nav_status still 0); the firmware "
                    f"ignores a start within 5-30 s of the previous one (a recent nav stop and "
                    f"start?): sending it again, giving up in {left:.0f} s",
                    markup=False,
                    style="yellow",
                )


# --- patrol, mapping, charging -------------------------------------------------------------


@patrol_app.command("start")
def patrol_start(
    ctx: typer.Context,
    dwell: Annotated[
        int | None, typer.Option(min=0, max=255, help="Seconds to wait at each target.")
    ] = None,
    start_nav: StartNav = None,
) -> None:
    """Start auto-patrol (navigation must be running)."""
    _simple(
        ctx,
        lambda robot: start_patrol(robot, dwell),
        "patrol running",
        navigation=start_nav,
        moving=True,
    )


async def start_patrol(robot: Robot, dwell: int | None) -> None:
    """Set the dwell (when given), then start patrol and wait for loop_status to show it.

    Firmware starts patrol on the dwell command ('m' 5 TT) alone; the document does not
    (docs/protocol.md §2.g), so 'm' 5 follows either way (a no-op on a running patrol).
    """
    if dwell is not None:
        await robot.set_patrol_dwell(dwell)
    await robot.start_patrol()


#: Commands that call one Robot method without arguments:
#: (group or None for top level, name, Robot method, line printed when done, help).
SIMPLE_COMMANDS: tuple[tuple[str | None, str, str, str, str], ...] = (
    ("nav", "stop", "stop_navigation", "navigation closed",
     "Stop navigation (also stops patrol and the goal)."),
    (None, "resume", "resume", "goal resumed", "Resume the paused goal."),
    ("patrol", "stop", "stop_patrol", "patrol stopped",
     "Stop auto-patrol and keep navigation (firmware 'm' 6)."),
    ("map", "start", "start_mapping", "mapping", "Start mapping (stops navigation)."),
    ("map", "stop", "stop_mapping", "mapping stopped", "Stop mapping."),
    ("map", "save", "save_map", "map save sent", "Save the map (some firmware ignores it)."),
    ("map", "update", "update_map", "map update sent", "Update the map."),
    ("charge", "start", "start_charging", "docking",
     "Dock and charge: the local infrared docking only, so the robot must already be near "
     "the dock with navigation open (drive it there first: goto / goto-point)."),
    ("charge", "stop", "stop_charging", "charging stopped", "Stop charging."),
    ("charge", "save-dock", "save_dock", "dock position saved",
     "Save the current pose as the dock position."),
)  # fmt: skip


def simple_command(method: str, done: str, help_text: str) -> Callable[[typer.Context], None]:
    """A command function that awaits ``robot.<method>()`` and prints ``done``."""

    def command(ctx: typer.Context) -> None:
        # Docking drives the robot: a stop signal during it stops the robot too.
        moving = method == "start_charging"
        _simple(ctx, lambda robot: getattr(robot, method)(), done, moving=moving)

    command.__doc__ = help_text
    return command


def shutdown(
    ctx: typer.Context,
    yes: Annotated[bool, typer.Option("--yes", help="Really power the computer off.")] = False,
) -> None:
    """Power the navigation computer off (needs --yes)."""
    if not yes:
        fail("shutdown powers the navigation computer off; pass --yes to confirm", ExitCode.USAGE)
    _simple(ctx, lambda robot: robot.shutdown_host(confirm=True), "shutdown sent")


# --- raw commands ------------------------------------------------------------------------------

_TRUE = {"1", "true", "yes", "on"}
_FALSE = {"0", "false", "no", "off"}


def _convert(kind: Any, text: str, name: str) -> object:
    kind = kind if isinstance(kind, str) else getattr(kind, "__name__", str(kind))
    try:
        if kind == "int":
            return int(text, 0)
        if kind == "float":
            return float(text)
        if kind == "bytes":
            return bytes.fromhex(text)
    except ValueError:
        raise InvalidArgument(f"{name} must be {kind}, got {text!r}") from None
    if kind == "bool":
        if text.lower() in _TRUE | _FALSE:
            return text.lower() in _TRUE
        raise InvalidArgument(f"{name} must be true or false, got {text!r}")
    return text


def parse_command(name: str, args: list[str]) -> Command:
    """Build a command from its class name (any case, ``-``/``_`` ignored) and text arguments."""
    by_key = {key.lower(): cls for key, cls in COMMAND_TYPES.items()}
    cls = by_key.get(name.replace("-", "").replace("_", "").lower())
    if cls is None:
        known = ", ".join(sorted(COMMAND_TYPES))
        raise InvalidArgument(f"unknown command {name!r}; known: {known}")
    fields = dataclasses.fields(cls)
    required = [f for f in fields if f.default is dataclasses.MISSING]
    if not len(required) <= len(args) <= len(fields):
        wanted = " ".join(f.name.upper() for f in fields) or "no arguments"
        raise InvalidArgument(f"{cls.name} takes {wanted}; got {len(args)} argument(s)")
    values = [_convert(f.type, text, f.name) for f, text in zip(fields, args, strict=False)]
    return cls(*values)


def send(
    ctx: typer.Context,
    command: Annotated[
        list[str] | None, typer.Argument(help="Command class name and arguments: Goto 3")
    ] = None,
    hex_payload: Annotated[
        str | None, typer.Option("--hex", help="Raw payload after the length byte: 6d00")
    ] = None,
) -> None:
    """Send one raw command, by class name with arguments or as a hex payload."""
    settings = settings_of(ctx)
    try:
        if hex_payload is not None:
            if command:
                raise InvalidArgument("give either a command name or --hex, not both")
            try:
                payload = bytes.fromhex(hex_payload)
            except ValueError:
                raise InvalidArgument(f"--hex needs hex digits, got {hex_payload!r}") from None
            to_send: Command = RawCommand(payload)
        elif command:
            to_send = parse_command(command[0], command[1:])
        else:
            raise InvalidArgument("name a command (e.g. `send Goto 3`) or pass --hex")
    except InvalidArgument as exc:
        fail(str(exc), ExitCode.USAGE)

    async def body(robot: Robot) -> int:
        await robot.send(to_send)
        wire = encode(to_send).hex(" ")
        if settings.json:
            print_json(settings, {"sent": to_send.name, "bytes": wire})
        else:
            out_console().print(f"sent {to_send!r}: {wire}", markup=False)
        return 0

    run_robot(settings, body)
