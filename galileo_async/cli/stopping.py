"""``galileo stop``, ``cancel`` and ``pause``: directly, or through the process that owns the port.

A serial port is opened exclusively and a robot's UDP port streams to one reader: while
another galileo process (``galileo goto``, an application connected with
``control_socket=True``) has the port, these three commands go through its control socket
(galileo_async.robot.control) and say so.
"""

from __future__ import annotations

import asyncio
import builtins
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Annotated, Any

import typer

from .. import errors
from ..errors import GalileoError, InvalidArgument, PortBusy
from ..robot.control import (
    ControlUnavailable,
    OwnerAnswer,
    ask_owner,
    control_key,
)
from ..robot.control_server import MAX_ASKED_TIMEOUT, control_operations
from ..robot.stopping import DEFAULT_STOP_TIMEOUT
from .goals import with_progress
from .runner import (
    ExitCode,
    Settings,
    exit_code_for,
    out_console,
    print_error,
    print_json,
    robot_url,
    run,
    settings_of,
)

if TYPE_CHECKING:
    from ..robot import Robot

__all__ = [
    "BrakeOption",
    "Outcome",
    "StopTimeout",
    "ask_first",
    "cancel",
    "owner_outcome",
    "pause",
    "stop",
]

BrakeOption = Annotated[
    int, typer.Option("--brake", min=0, max=100, help="Brake strength of the speed stop, 0-100.")
]
StopTimeout = Annotated[
    float,
    typer.Option(
        "--timeout", "-t", min=0.1, max=MAX_ASKED_TIMEOUT,
        help="Seconds for the robot to show it stopped (then exit code 6).",
    ),
]  # fmt: skip
JsonFlag = Annotated[bool, typer.Option("--json", help="Print the result as JSON.")]


@dataclass
class Outcome:
    """One robot's outcome of stop, cancel or pause: the answer's fields, or why not."""

    fields: dict[str, Any] = field(default_factory=dict)
    code: ExitCode = ExitCode.OK
    error: str | None = None
    message: str = ""
    #: The owning process it went through: (pid, command line), else None.
    owner: tuple[int | None, str] | None = None

    @property
    def done(self) -> str:
        """What was done, in words."""
        return str(self.fields.get("done", ""))

    def why(self) -> str:
        """The error's message, and the owning process it came from."""
        where = "" if self.owner is None else f" (in process {self.owner[0]}, which owns it)"
        return f"{self.message}{where}"

    def text(self) -> str:
        """The result line: what was done, and through which process; or the error."""
        if self.error is not None:
            return f"{self.error}: {self.why()}"
        if self.owner is None:
            return self.done
        pid, command = self.owner
        return f"{self.done} (through the owning process {pid}: {command})"

    def data(self) -> dict[str, Any]:
        """The JSON fields (after ``"port"``)."""
        data: dict[str, Any] = {"result": "ok", **self.fields}
        if self.error is not None:
            data = {"result": "error", "error": self.error, "message": self.message,
                    "exit_code": int(self.code)} | self.fields  # fmt: skip
        if self.owner is not None:
            data["owner"] = {"pid": self.owner[0], "command": self.owner[1]}
        return data


def _error_type(name: str) -> type[BaseException] | None:
    found = getattr(errors, name, None) or getattr(builtins, name, None)
    return found if isinstance(found, type) and issubclass(found, BaseException) else None


def owner_outcome(answer: OwnerAnswer) -> Outcome:
    """The Outcome of an owning process's answer; its error's exit code by the type's name."""
    owner = (answer.pid, answer.command)
    fields = {k: v for k, v in answer.fields.items() if k not in ("ok", "pid", "argv")}
    if answer.ok:
        return Outcome(fields, owner=owner)
    kind = _error_type(answer.error)
    code = ExitCode.ERROR if kind is None else exit_code_for(kind)
    extra = {k: v for k, v in fields.items() if k not in ("error", "message")}
    return Outcome(extra, code, answer.error, answer.message, owner)


def error_outcome(exc: BaseException, code: ExitCode | None = None) -> Outcome:
    """The Outcome of an error raised here."""
    extra: dict[str, Any] = {}
    unconfirmed = getattr(exc, "unconfirmed", None)
    if isinstance(unconfirmed, tuple):
        extra["unconfirmed"] = list(unconfirmed)
    code = exit_code_for(exc) if code is None else code
    return Outcome(extra, code, type(exc).__name__, str(exc) or type(exc).__name__)


async def ask_first(url: str, op: str, request: Mapping[str, Any]) -> Outcome | str:
    """The owning process's Outcome of ``op``, or why none answered (nobody serves the port)."""
    try:
        if control_key(url) is None:
            return "this kind of port has no control socket"
    except InvalidArgument as exc:  # a bad URL: connect() says so
        return str(exc)
    try:
        brake, timeout = request.get("brake"), request.get("timeout")
        answer = await ask_owner(url, op, brake=brake, timeout=timeout)
    except ControlUnavailable as exc:  # NoOwner among them
        return str(exc)
    return owner_outcome(answer)


def _busy(busy: PortBusy, op: str, why: str) -> PortBusy:
    note = "" if why.startswith("no process") else f" ({why})"
    return PortBusy(
        f"{busy}; no galileo process serves its control socket{note}, so {op} cannot go "
        "through it (a program that does not use galileo_async, or an application that "
        "connected without control_socket=True)",
        port=busy.port,
    )


async def stop_cancel_pause(settings: Settings, url: str, op: str, request: dict[str, Any]) -> int:
    """Run ``op`` through the port's owner when there is one, else on a connection of our own."""
    from ..robot import connect

    first = await ask_first(url, op, request)
    if isinstance(first, Outcome):
        return _show(settings, first)
    try:
        async with connect(url, **settings.connect_options()) as robot:
            fields = await _direct(settings, robot, op, request)
    except PortBusy as busy:  # the owner may have started meanwhile: ask once more
        again = await ask_first(url, op, request)
        if not isinstance(again, Outcome):
            raise _busy(busy, op, again) from busy
        return _show(settings, again)
    return _show(settings, Outcome(fields))


async def _direct(settings: Settings, robot: Robot, op: str, request: dict[str, Any]) -> Any:
    call = control_operations(robot)[op](request)
    return await with_progress(robot, op, call, show=not settings.json)


def _show(settings: Settings, outcome: Outcome) -> int:
    if outcome.error is not None:  # JSON names the type in "error" already
        message = outcome.why() if settings.json else outcome.text()
        print_error(message, kind=outcome.error, code=outcome.code)
    elif settings.json:
        print_json(settings, outcome.data())
    else:
        out_console().print(outcome.text(), markup=False)
    return int(outcome.code)


def _command(ctx: typer.Context, op: str, request: dict[str, Any], json_output: bool) -> None:
    settings = settings_of(ctx)
    settings.json = settings.json or json_output
    url = robot_url(settings)
    run(settings, lambda: stop_cancel_pause(settings, url, op, request))


def stop(
    ctx: typer.Context,
    brake: BrakeOption = 100,
    timeout: StopTimeout = DEFAULT_STOP_TIMEOUT,
    json_output: JsonFlag = False,
) -> None:
    """Stop everything: cancel the goal, stop patrol, end driving, zero the speeds.

    The command that stops everything the robot is doing (`nav stop`, `patrol stop` and
    `charge stop` each stop one service); returns once the robot shows it stopped, and
    prints what was stopped (exit code 6 when it does not confirm within --timeout). While
    another galileo process has the port open (`galileo goto` in another terminal), the
    stop goes through that process.
    """
    _command(ctx, "stop", {"brake": brake, "timeout": timeout}, json_output)


def cancel(ctx: typer.Context, json_output: JsonFlag = False) -> None:
    """Cancel the goal (says so when no goal was running); through the port's owner if any."""
    _command(ctx, "cancel", {}, json_output)


def pause(ctx: typer.Context, json_output: JsonFlag = False) -> None:
    """Pause the working goal; through the port's owner if another process has the port."""
    _command(ctx, "pause", {}, json_output)


async def gather_owners(
    ports: Mapping[str, str], op: str, request: Mapping[str, Any]
) -> dict[str, Outcome | str]:
    """ask_first for every port at once: an Outcome where an owner answered (or failed to:
    an owner that does not answer is the robot's error), else why none did."""

    async def ask(url: str) -> Outcome | str:
        try:
            return await ask_first(url, op, request)
        except GalileoError as exc:  # GalileoTimeout, GalileoConnectionError
            return error_outcome(exc)

    names = list(ports)
    found = await asyncio.gather(*(ask(ports[name]) for name in names))
    return dict(zip(names, found, strict=True))
