"""``galileo teleop``: drive by keys from a terminal; a stop is always sent on the way out."""

from __future__ import annotations

import asyncio
import os
import sys
from typing import TYPE_CHECKING, Annotated

import anyio
import typer

from ..errors import GalileoError
from .runner import (
    ExitCode,
    err_console,
    error_text,
    fail,
    out_console,
    print_error,
    run_robot,
    settings_of,
)

if TYPE_CHECKING:
    from ..robot import Robot

__all__ = ["KEYS", "parse_keys", "teleop"]

#: Key sequences (bytes from a terminal in cbreak mode) and the action each one means.
KEYS: dict[bytes, str] = {
    b"w": "forward", b"\x1b[A": "forward", b"\x1bOA": "forward",
    b"s": "backward", b"\x1b[B": "backward", b"\x1bOB": "backward",
    b"a": "left", b"\x1b[D": "left", b"\x1bOD": "left",
    b"d": "right", b"\x1b[C": "right", b"\x1bOC": "right",
    b" ": "stop",
    b"+": "faster", b"=": "faster", b"-": "slower",
    b"q": "quit", b"\x03": "quit", b"\x04": "quit",
}  # fmt: skip
_ESCAPES = tuple(key for key in KEYS if key.startswith(b"\x1b"))
HELP = "keys: w/↑ forward · s/↓ back · a/← left · d/→ right · space stop · +/- speed · q quit"
#: Seconds allowed for the final stop command on the way out.
STOP_TIMEOUT = 2.0
SPEED_STEP = 10


def parse_keys(data: bytes) -> tuple[list[str], bytes]:
    """Split terminal input into actions; return them and an unfinished escape sequence."""
    actions: list[str] = []
    pos = 0
    while pos < len(data):
        if data[pos] == 0x1B:
            sequence = data[pos : pos + 3]
            if len(sequence) < 3 and any(key.startswith(sequence) for key in _ESCAPES):
                return actions, data[pos:]
            action = KEYS.get(sequence)
            if action is not None:
                actions.append(action)
                pos += 3
                continue
            pos += 1  # an escape sequence we do not use: skip its ESC, the rest falls through
            continue
        action = KEYS.get(data[pos : pos + 1].lower())
        if action is not None:
            actions.append(action)
        pos += 1
    return actions, b""


async def _apply(robot: Robot, action: str, percent: int) -> int:
    console = out_console()
    if action == "faster":
        percent = min(100, percent + SPEED_STEP)
        console.print(f"speed {percent}%")
    elif action == "slower":
        percent = max(SPEED_STEP, percent - SPEED_STEP)
        console.print(f"speed {percent}%")
    elif action == "stop":
        await robot.stop()
        console.print("stop")
    else:
        move = {
            "forward": robot.forward,
            "backward": robot.backward,
            "left": robot.turn_left,
            "right": robot.turn_right,
        }[action]
        await move(percent)
        console.print(f"{action} {percent}%")
    return percent


async def _drive(robot: Robot, fd: int, percent: int) -> None:
    loop = asyncio.get_running_loop()
    chunks: asyncio.Queue[bytes] = asyncio.Queue()

    def readable() -> None:
        try:
            data = os.read(fd, 64)
        except OSError:  # the terminal went away
            data = b""
        if not data:
            loop.remove_reader(fd)
        chunks.put_nowait(data)

    loop.add_reader(fd, readable)
    try:
        pending = b""
        while True:
            chunk = await chunks.get()
            if not chunk:
                return
            actions, pending = parse_keys(pending + chunk)
            for action in actions:
                if action == "quit":
                    return
                percent = await _apply(robot, action, percent)
    finally:
        loop.remove_reader(fd)


def teleop(
    ctx: typer.Context,
    speed: Annotated[int, typer.Option(min=1, max=100, help="Start speed, % of max.")] = 30,
) -> None:
    """Drive with the keyboard (arrows or WASD); space stops, q quits, stop is sent on exit."""
    settings = settings_of(ctx)
    if not sys.stdin.isatty():
        fail("teleop needs an interactive terminal (stdin is not a tty)")
    try:
        import termios
        import tty
    except ImportError:  # pragma: no cover - Windows
        fail("teleop needs a POSIX terminal (termios)")
    fd = sys.stdin.fileno()

    async def body(robot: Robot) -> int:
        saved = termios.tcgetattr(fd)
        tty.setcbreak(fd)
        try:
            status = robot.status
            if status is not None and status.goal_active:
                # Teleop and planner speeds override each other (PROTOCOL.md §2.e).
                await robot.cancel()
                err_console().print("cancelled the running goal to take over")
            err_console().print(HELP)
            await _drive(robot, fd, speed)
        finally:
            termios.tcsetattr(fd, termios.TCSADRAIN, saved)
            with anyio.move_on_after(STOP_TIMEOUT, shield=True):
                try:
                    await robot.stop()
                    out_console().print("stop (on exit)")
                except GalileoError as exc:
                    print_error(f"could not send stop on exit: {error_text(exc)}")
        return 0

    run_robot(settings, body, interrupted=ExitCode.OK)
