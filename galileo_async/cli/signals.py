"""Ctrl-C, SIGTERM and SIGHUP: one way out of every command (docs/cli.md, "Signals").

run() (runner.py) handles STOP_SIGNALS while a command's main runs: the first one cancels
the main task, as Ctrl-C does, or sets the events of stop_requested() blocks (commands
whose normal end is a stop). A command that moves the robot wraps that in
stop_on_interrupt(): on its way out, after what the command sent itself (a goal's
cancel, a drive's stop), the robot is stopped once, and the Interruption says so.
"""

from __future__ import annotations

import asyncio
import contextlib
import signal
from collections.abc import AsyncIterator, Awaitable, Callable, Iterator
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Protocol

import anyio

from ..errors import ConnectionLost, StopUnconfirmed, UnconfirmedOperation
from .output import err_console, print_json, timestamp
from .render import pose_text, rounded

if TYPE_CHECKING:
    from ..models import GalileoStatus
    from ..robot import Robot

__all__ = [
    "STOP_ON_EXIT_TIMEOUT",
    "STOP_SIGNALS",
    "Interruption",
    "Stops",
    "handling",
    "interruption",
    "pose_json",
    "running",
    "stop_on_interrupt",
    "stop_requested",
    "stop_signal",
]

#: The signals that end a command the way Ctrl-C does.
STOP_SIGNALS: tuple[signal.Signals, ...] = tuple(
    getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, name)
)
#: Seconds the stop on the way out of an interrupted command may take (Robot.stop()'s own
#: timeout; a second more for its answer).
STOP_ON_EXIT_TIMEOUT = 5.0


@dataclass
class Interruption:
    """What a command stopped by a signal did on its way out: the words of its last line."""

    #: The signal that stopped it; None when Python's own Ctrl-C handling did.
    signal: signal.Signals | None
    #: What went to the robot on the way out, in order ("goal 3 cancelled (i 2 sent)", …).
    done: list[str] = field(default_factory=list)
    #: Where the robot was once stopped (pose_text), when a robot was stopped.
    where: str | None = None
    #: The fields of the line as JSON (--json), besides time, result and signal.
    fields: dict[str, Any] = field(default_factory=dict)

    @property
    def name(self) -> str:
        """``SIGTERM``, ``SIGHUP``, ``SIGINT`` (Ctrl-C)."""
        return "SIGINT" if self.signal is None else self.signal.name

    def line(self) -> str:
        """``interrupted by SIGTERM: goal 3 cancelled (i 2 sent), stop sent; robot at (…) …``."""
        done = ", ".join(self.done) or "nothing sent"
        where = "" if self.where is None else f"; robot at {self.where}"
        return f"interrupted by {self.name}: {done}{where}"


class _Invocation(Protocol):
    """What say() needs of the invocation's Settings."""

    @property
    def json(self) -> bool:
        """--json was given."""

    @property
    def port(self) -> str:
        """The port as given."""


class Stops:
    """The stop signals of one run(): the first cancels the command (or sets its stop events)."""

    def __init__(self) -> None:
        self.task: asyncio.Task[Any] | None = None
        #: The first stop signal received; None before one.
        self.signal: signal.Signals | None = None
        self.events: list[asyncio.Event] = []
        #: What the command noted on its way out; None when it noted nothing.
        self.interruption: Interruption | None = None

    def received(self, number: signal.Signals) -> None:
        """A stop signal arrived (a callback of the loop, not of the signal handler)."""
        if self.signal is not None:
            # The way out (a cancel, a stop, OFFLINE) is bounded: it is not cut short.
            with contextlib.suppress(OSError, ValueError):  # a terminal that hung up
                err_console().print(
                    f"galileo: {number.name} again: still stopping after {self.signal.name} "
                    "(each step is bounded; SIGKILL ends at once, without a stop)",
                    markup=False,
                )
            return
        self.signal = number
        if self.events:
            for event in self.events:
                event.set()
        elif self.task is not None and not self.task.done():
            self.task.cancel()

    def note(self) -> Interruption:
        """The Interruption to tell what the command sends on its way out."""
        if self.interruption is None:
            self.interruption = Interruption(self.signal)
        return self.interruption

    def exit_code(self, error: BaseException, interrupted: int) -> int | None:
        """The exit code of a command that ``error`` shows a stop signal ended; None: not so.

        Ctrl-C (KeyboardInterrupt, or a cancel after SIGINT): ``interrupted``; a cancel after
        SIGTERM or SIGHUP: 128 + the signal's number (143, 129).
        """
        if isinstance(error, KeyboardInterrupt):
            return int(interrupted)
        if not isinstance(error, asyncio.CancelledError) or self.signal is None:
            return None
        return int(interrupted) if self.signal == signal.SIGINT else 128 + int(self.signal)

    def say(self, settings: _Invocation) -> None:
        """The line of an interrupted command (--json: one object on stdout), if it noted one."""
        note = self.interruption
        if note is None or not note.done:
            return
        # A terminal that hung up cannot take it: the robot was stopped all the same.
        with contextlib.suppress(OSError, ValueError):
            if settings.json:
                payload = {"result": "interrupted", "signal": note.name, **note.fields}
                print_json(settings, {"time": timestamp(), **payload})
            else:
                err_console().print(note.line(), markup=False)


#: The Stops of the running run() calls, innermost last.
_running: list[Stops] = []


@contextlib.contextmanager
def running(stops: Stops) -> Iterator[Stops]:
    """``stops`` are those of the command that runs in the block (run() uses it)."""
    _running.append(stops)
    try:
        yield stops
    finally:
        _running.remove(stops)


async def handling(stops: Stops, main: Callable[[], Awaitable[int | None]]) -> int | None:
    """``await main()`` with STOP_SIGNALS handled by ``stops`` (in the main thread only)."""
    loop = asyncio.get_running_loop()
    stops.task = asyncio.current_task()
    installed: dict[signal.Signals, Any] = {}
    for number in STOP_SIGNALS:
        previous = signal.getsignal(number)
        try:
            loop.add_signal_handler(number, stops.received, number)
        except (NotImplementedError, RuntimeError, ValueError):  # not the main thread
            continue
        installed[number] = previous
    try:
        return await main()
    finally:
        for number, previous in installed.items():
            loop.remove_signal_handler(number)
            with contextlib.suppress(TypeError, ValueError):
                signal.signal(number, previous)


def stop_signal() -> signal.Signals | None:
    """The stop signal (STOP_SIGNALS) that is ending the running command; None before one."""
    return _running[-1].signal if _running else None


def interruption() -> Interruption:
    """The running command's Interruption, to tell what it sends on its way out."""
    if not _running:  # outside run(): a record nobody prints
        return Interruption(None)
    return _running[-1].note()


@contextlib.contextmanager
def stop_requested() -> Iterator[asyncio.Event]:
    """An event set by Ctrl-C, SIGTERM or SIGHUP while the block runs, for a clean stop.

    Inside run() a stop signal then sets the event instead of cancelling the command, and
    stop_signal() names it; the command ends as it returns. Outside run(): Ctrl-C only.
    """
    event = asyncio.Event()
    if _running and _running[-1].task is not None:
        stops = _running[-1]
        stops.events.append(event)
        if stops.signal is not None:
            event.set()
        try:
            yield event
        finally:
            stops.events.remove(event)
        return
    loop = asyncio.get_running_loop()
    installed = False
    with contextlib.suppress(NotImplementedError, RuntimeError, ValueError):
        loop.add_signal_handler(signal.SIGINT, event.set)
        installed = True
    try:
        yield event
    finally:
        if installed:
            loop.remove_signal_handler(signal.SIGINT)


@contextlib.asynccontextmanager
async def stop_on_interrupt(robot: Robot) -> AsyncIterator[None]:
    """A block that moves ``robot``: cancelled (a stop signal), it stops the robot once.

    After what the block sent on its own way out (a goal's cancel, a drive's stop),
    ``robot.stop()`` runs bounded and shielded; the Interruption's line says how it went
    and where the robot is.
    """
    try:
        yield
    except asyncio.CancelledError:
        note = interruption()
        note.done.append(await _stop_shielded(robot, note))
        note.where = pose_text(robot.status)
        note.fields["pose"] = pose_json(robot.status)
        raise


def pose_json(status: GalileoStatus | None) -> dict[str, float] | None:
    """The pose of ``status`` as JSON, rounded as shown (``{"x", "y", "degrees"}``), or None."""
    pose = None if status is None else status.pose
    if pose is None:
        return None
    return {"x": rounded("x", pose.x), "y": rounded("y", pose.y), "degrees": round(pose.degrees, 1)}


async def _stop_shielded(robot: Robot, note: Interruption) -> str:
    """``robot.stop()``, whatever cancels the caller; the words for the line (and the JSON)."""
    task = asyncio.ensure_future(robot.stop(timeout=STOP_ON_EXIT_TIMEOUT))
    with anyio.CancelScope(shield=True):
        done, _ = await asyncio.wait((task,), timeout=STOP_ON_EXIT_TIMEOUT + 1.0)
        if not done:
            task.cancel()
            await asyncio.wait((task,))
    if task.cancelled():
        note.fields.update(stop_sent=False, stop=f"no answer in {STOP_ON_EXIT_TIMEOUT + 1:g} s")
        return f"stop not confirmed ({note.fields['stop']})"
    error = task.exception()
    note.fields["stop_sent"] = error is None or isinstance(error, UnconfirmedOperation)
    if isinstance(error, StopUnconfirmed):
        note.fields["stop"] = "unconfirmed: " + ", ".join(error.unconfirmed)
        return f"stop sent, not confirmed ({', '.join(error.unconfirmed)})"
    if isinstance(error, UnconfirmedOperation):
        note.fields["stop"] = f"unconfirmed: {error}"
        return "stop sent, not confirmed"
    if error is not None:
        note.fields["stop"] = f"{type(error).__name__}: {error}"
        what = "link lost" if isinstance(error, ConnectionLost) else type(error).__name__
        return f"stop not sent ({what})"
    stopped = task.result()
    note.fields["stop"] = str(stopped)
    return f"stop sent ({stopped})" if stopped.stopped else "stop sent"
