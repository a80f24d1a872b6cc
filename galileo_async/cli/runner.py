"""Shared plumbing of the CLI: settings, exit codes, error reporting, running a robot session."""

from __future__ import annotations

import asyncio
import contextlib
import enum
import json
import os
import sys
from collections.abc import Awaitable, Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal, NoReturn
from urllib.parse import parse_qsl, urlencode, urlsplit

import typer
from rich.markup import escape

from ..errors import (
    DuplicateVehicle,
    GalileoConnectionError,
    GalileoError,
    GalileoTimeout,
    GoalAborted,
    GoalCancelled,
    GoalRejected,
    GoalStalled,
    InvalidArgument,
    NotReady,
    PortBusy,
)
from ..links import link_kind, url_forms
from .logs import setup_logging
from .output import err_console, out_console, print_json, timestamp
from .signals import Stops, handling, running, stop_on_interrupt

if TYPE_CHECKING:
    from ..robot import Robot

__all__ = [
    "DEFAULT_PORT",
    "PORT_ENV",
    "SIMULATOR_NOTICE",
    "ExitCode",
    "PortSource",
    "Settings",
    "checked_port",
    "ensure_navigation",
    "err_console",
    "error_text",
    "exit_code_for",
    "fail",
    "is_sim",
    "out_console",
    "print_error",
    "print_json",
    "report",
    "resolve_port",
    "robot_url",
    "run",
    "run_robot",
    "settings_of",
    "setup_logging",
    "timestamp",
    "with_query",
]

#: The URL used when neither --port nor GALILEO_PORT is given: an in-process simulator.
DEFAULT_PORT = "sim://"
#: The environment variable that names the port when --port is not given.
PORT_ENV = "GALILEO_PORT"
#: Where the port of an invocation came from.
PortSource = Literal["--port", "GALILEO_PORT", "--robot", "GALILEO_ROBOT", "default"]
#: The stderr line of every robot command that runs on the simulator by default.
SIMULATOR_NOTICE = (
    f"galileo: no --port or {PORT_ENV} given: running on the built-in simulator ({DEFAULT_PORT})"
)


#: The Settings of the running invocation (the last made): print_error asks it for --json.
_current: list[Settings] = []


class ExitCode(enum.IntEnum):
    """Process exit codes of the ``galileo`` command (documented in docs/cli.md)."""

    OK = 0  # done; for goto: arrived
    ERROR = 1  # any other error (I/O, a command the robot never confirmed, …)
    USAGE = 2  # bad command line or argument out of range; nothing was sent
    REJECTED = 3  # the robot reported an error for the goal (invalid id)
    ABORTED = 4  # the goal ended far from the target (planner gave up), or made no progress
    CANCELLED = 5  # the goal was cancelled or preempted by another goal
    TIMEOUT = 6  # an operation ran past its timeout
    CONNECTION = 7  # the link could not be opened, dropped or went stale
    NOT_READY = 8  # a precondition failed (e.g. navigation not open); nothing was sent
    PORT_BUSY = 9  # the serial port is open in another process or connection
    DUPLICATE_VEHICLE = 10  # vda5050: another vehicle with this identity is on the broker
    INTERRUPTED = 130  # Ctrl-C (SIGINT); SIGTERM and SIGHUP: 128 + their number (143, 129)


@dataclass
class Settings:
    """Global options of one ``galileo`` invocation."""

    port: str = DEFAULT_PORT
    #: "default" when neither --port nor GALILEO_PORT named the port (the simulator stands in).
    port_source: PortSource = "--port"
    layout: str | None = None
    verbose: int = 0
    json: bool = False
    map_targets: int | None = None
    extra: dict[str, Any] = field(default_factory=dict)
    #: The fleet file of ``--fleet`` (fleet commands).
    fleet: Path | None = None

    def __post_init__(self) -> None:
        _current[:] = [self]  # the invocation's settings: print_error asks for --json

    @property
    def url(self) -> str:
        """The URL to connect to; for sim:// the global --layout also sets the sim's layout."""
        if not is_sim(self.port) or self.layout is None:
            return self.port
        return with_query(self.port, layout=self.layout)

    def connect_options(self, *, long_running: bool = False) -> dict[str, Any]:
        """Keyword options for ``galileo_async.connect`` (watchers keep reconnecting)."""
        options: dict[str, Any] = dict(self.extra)
        if self.layout is not None:
            options["layout"] = self.layout
        if self.map_targets is not None:
            options["map_targets"] = self.map_targets
        elif is_sim(self.port):
            # The simulator's map is known: goto-point works on sim:// without --map-targets.
            from ..sim import parse_sim_url

            options["map_targets"] = len(parse_sim_url(self.url).targets)
        if not is_sim(self.port) and not long_running:
            # A one-shot command should fail at once on a dead link, not retry forever.
            options.setdefault("reconnect", False)
        if link_kind(self.port) in ("serial", "udp"):  # stop/cancel/pause from other terminals
            options.setdefault("control_socket", True)
        return options


def with_query(url: str, **defaults: str) -> str:
    """``url`` with query options added where it does not set them already."""
    parts = urlsplit(url)
    query = dict(parse_qsl(parts.query))
    for key, value in defaults.items():
        query.setdefault(key, value)
    # Spelled out: urlunsplit would drop the "//" of "sim://" when the host is empty.
    return f"{parts.scheme}://{parts.netloc}{parts.path}?{urlencode(query)}"


def is_sim(url: str) -> bool:
    """True for the in-process simulator URL (``sim://…``)."""
    return link_kind(url) == "sim"


def resolve_port(option: str | None, *, from_environment: bool = False) -> tuple[str, PortSource]:
    """(port, source): --port, else GALILEO_PORT (kept even when empty), else the simulator."""
    if option is not None:
        return option, "GALILEO_PORT" if from_environment else "--port"
    environment = os.environ.get(PORT_ENV)
    if environment is not None:  # set but empty: a usage error later, never the simulator
        return environment, "GALILEO_PORT"
    return DEFAULT_PORT, "default"


def settings_of(ctx: typer.Context) -> Settings:
    """The Settings stored by the global callback (defaults when run without it)."""
    root = ctx.find_root()
    if not isinstance(root.obj, Settings):
        port, source = resolve_port(None)
        root.obj = Settings(port=port, port_source=source)
    root.call_on_close(_current.clear)  # the invocation is over: no JSON errors after it
    return root.obj


def checked_port(settings: Settings) -> str:
    """The port of ``settings``; an empty --port or GALILEO_PORT exits with ExitCode.USAGE."""
    if not settings.port.strip():
        fail(
            f"{settings.port_source} is empty: name the robot's port ({url_forms()}; "
            f"{DEFAULT_PORT} for the simulator)",
            ExitCode.USAGE,
        )
    return settings.port


def robot_url(settings: Settings) -> str:
    """The URL a robot command opens (checked_port); says so on stderr when it is the default."""
    checked_port(settings)
    if settings.port_source == "default":
        err_console().print(SIMULATOR_NOTICE, markup=False, style="yellow")
    return settings.url


_CODES: tuple[tuple[type[BaseException], ExitCode], ...] = (
    # Order matters: AcceptTimeout is both a GoalError and a GalileoTimeout.
    (GalileoTimeout, ExitCode.TIMEOUT),
    (GoalRejected, ExitCode.REJECTED),
    (GoalAborted, ExitCode.ABORTED),
    (GoalStalled, ExitCode.ABORTED),
    (GoalCancelled, ExitCode.CANCELLED),
    (PortBusy, ExitCode.PORT_BUSY),
    (DuplicateVehicle, ExitCode.DUPLICATE_VEHICLE),
    (GalileoConnectionError, ExitCode.CONNECTION),
    (NotReady, ExitCode.NOT_READY),
    (InvalidArgument, ExitCode.USAGE),
    (TimeoutError, ExitCode.TIMEOUT),
    (ConnectionError, ExitCode.CONNECTION),
)


def exit_code_for(exc: BaseException | type[BaseException]) -> ExitCode:
    """The exit code that reports ``exc`` (an error, or its type)."""
    error_type = exc if isinstance(exc, type) else type(exc)
    for kind, code in _CODES:
        if issubclass(error_type, kind):
            return code
    return ExitCode.ERROR


#: Operations (the start of their errors) whose commands have --start-nav.
_START_NAV_OPERATIONS = ("goto", "rotate", "start_patrol", "set_patrol_dwell")


def _hint(exc: BaseException) -> str:
    text = str(exc).lower()
    if not isinstance(exc, NotReady) or "navigation" not in text or "not reported" in text:
        return ""
    if "must be closed" in text:
        return " (close navigation first: `galileo nav stop`)"
    more = ", or pass --start-nav" if text.startswith(_START_NAV_OPERATIONS) else ""
    return f" (start it with `galileo nav start`{more})"


def error_text(exc: BaseException) -> str:
    """``Kind: message``: the error's type name, then its message."""
    return f"{type(exc).__name__}: {str(exc) or type(exc).__name__}"


def _json_wanted() -> bool:
    """True when the running command was asked for --json (errors are then JSON too)."""
    return bool(_current) and _current[-1].json


def print_error(message: str, *, kind: str = "error", code: ExitCode = ExitCode.ERROR) -> None:
    """``error: message`` on stderr; with --json ``{"error": kind, "message", "exit_code"}``."""
    if _json_wanted():
        data = {"error": kind, "message": message, "exit_code": int(code)}
        out_console().print(json.dumps(data), markup=False)
        return
    err_console().print(f"[bold red]error:[/] {escape(message)}", highlight=False)


def report(exc: BaseException, verbose: int) -> ExitCode:
    """Print one clear line for ``exc`` (a traceback too with -v) and return its exit code."""
    code = exit_code_for(exc)
    if verbose:
        err_console().print_exception(show_locals=False)
    bug = "" if isinstance(exc, _REPORTED) else " (a bug: -v shows where)"
    if _json_wanted():
        message = (str(exc) or type(exc).__name__) + _hint(exc) + bug
        print_error(message, kind=type(exc).__name__, code=code)
    else:
        print_error(error_text(exc) + _hint(exc) + bug)
    return code


def fail(message: str, code: ExitCode = ExitCode.ERROR) -> NoReturn:
    """Print ``message`` as an error line and exit with ``code``."""
    print_error(message, kind=code.name.lower(), code=code)
    raise typer.Exit(int(code))


def run(
    settings: Settings,
    main: Callable[[], Awaitable[int | None]],
    *,
    interrupted: ExitCode = ExitCode.INTERRUPTED,
) -> NoReturn:
    """Run ``main`` on a fresh event loop and exit with its code or the code of its error.

    Every error ends as one line (report); a reader that closed stdout (``| head``) ends
    the command quietly: exit 0 for a command that Ctrl-C ends normally, else 1 (as Python).
    SIGTERM and SIGHUP end ``main`` as Ctrl-C does, with 128 + their number (signals.py).
    """
    with running(Stops()) as stops:
        try:
            code = asyncio.run(handling(stops, main))
        except KeyboardInterrupt:
            code = int(interrupted)
        except BaseException as exc:  # task groups wrap even SystemExit
            error = _first_leaf(exc)  # task groups wrap what their tasks raised
            if _stdout_closed(error):
                code = int(ExitCode.OK if interrupted == ExitCode.OK else ExitCode.ERROR)
            elif (stopped := stops.exit_code(error, interrupted)) is not None:
                code = stopped
            elif isinstance(error, (SystemExit, typer.Exit, typer.Abort, typer.TyperException)):
                raise error from None
            else:
                code = int(report(error, settings.verbose))
    stops.say(settings)
    raise typer.Exit(int(code or 0))


def _stdout_closed(error: BaseException) -> bool:
    """True for a write to a stdout its reader closed (rich turns that into SystemExit(1))."""
    broken = isinstance(error, BrokenPipeError) or (
        isinstance(error, SystemExit) and isinstance(error.__context__, BrokenPipeError)
    )
    if broken:
        # Python's advice (library/signal.html#note-on-sigpipe): point stdout at devnull so
        # that the flush at exit does not fail once more.
        with contextlib.suppress(OSError, ValueError):  # a stdout without a descriptor
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, sys.stdout.fileno())
    return broken


#: Errors reported as one line of their own; anything else is a bug, reported as such.
_REPORTED = (GalileoError, OSError, TimeoutError, ValueError)


def _first_leaf(exc: BaseException) -> BaseException:
    children = getattr(exc, "exceptions", None)  # an exception group's members
    while isinstance(children, tuple) and children:
        exc = children[0]
        children = getattr(exc, "exceptions", None)
    return exc


def run_robot(
    settings: Settings,
    body: Callable[[Robot], Awaitable[int | None]],
    *,
    navigation: bool | None = False,
    interrupted: ExitCode = ExitCode.INTERRUPTED,
    long_running: bool = False,
    moving: bool = False,
    metrics: tuple[str, int] | None = None,
) -> NoReturn:
    """Connect (connect waits for the first status), maybe open navigation, run ``body``, exit.

    ``metrics``: (host, port) of a Prometheus endpoint served around it all, the robot
    labelled by its URL (metrics_opt.py; bound before connecting).

    ``navigation``: False = leave it alone; True = start it when it is closed; None = start
    it only on sim:// (each invocation gets a fresh simulated robot with navigation closed).
    ``long_running`` commands (watchers) reconnect after a drop; one-shot commands do not.
    ``moving`` commands stop the robot once when a stop signal ends them (stop_on_interrupt).
    """

    url = robot_url(settings)

    async def main() -> int | None:
        from ..robot import connect
        from .metrics_opt import metrics_served

        options = settings.connect_options(long_running=long_running)
        async with metrics_served(metrics) as served, connect(url, **options) as robot:
            if served is not None:
                served.add_robot(robot, name=url)
            start = is_sim(settings.port) if navigation is None else navigation
            if start:
                await ensure_navigation(robot, settings)
            async with stop_on_interrupt(robot) if moving else contextlib.nullcontext():
                return await body(robot)

    run(settings, main, interrupted=interrupted)


async def ensure_navigation(robot: Robot, settings: Settings) -> None:
    """Start navigation (and wait for the visual system) unless it is already running."""
    status = robot.status
    if status is not None and status.navigating and status.visual_initialised:
        return
    note = " (sim:// is a fresh simulated robot on every run)" if is_sim(settings.port) else ""
    err_console().print(f"[dim]starting navigation{note}…[/]")
    await robot.start_navigation()
