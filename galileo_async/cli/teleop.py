"""``galileo teleop``: drive by keys from a terminal; a stop is always sent on the way out."""

from __future__ import annotations

import asyncio
import contextlib
import os
import sys
from typing import TYPE_CHECKING, Annotated

import typer

from .runner import (
    ExitCode,
    err_console,
    fail,
    out_console,
    run_robot,
    settings_of,
)

if TYPE_CHECKING:
    from ..robot import DriveSession, Robot

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
SPEED_STEP = 10
#: Seconds without a key repeat after which a held key counts as released (and stops).
RELEASE_AFTER = 0.5
#: Hz at which the speed is kept alive (chassis watchdogs stop after 1 to 3 s).
DRIVE_RATE = 10.0


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


class _Keys:
    """What the keys ask for: a percentage of the robot's limits, a direction, held or not."""

    def __init__(self, robot: Robot, percent: int) -> None:
        self.limits = robot.speed_limits
        self.percent = percent

    def velocity(self, action: str) -> tuple[float, float]:
        """(linear m/s, angular rad/s) of a direction key at the current percentage."""
        linear, angular = _DIRECTIONS[action]
        share = self.percent / 100
        return linear * share * self.limits.linear, angular * share * self.limits.angular


#: Direction keys: the sign of (linear, angular); one key is held at a time.
_DIRECTIONS = {
    "forward": (1, 0), "backward": (-1, 0), "left": (0, 1), "right": (0, -1),
}  # fmt: skip


def _apply(drive: DriveSession, keys: _Keys, action: str) -> bool:
    """Apply one action; True while a direction key is held (its speed is kept alive)."""
    console = out_console()
    if action in ("faster", "slower"):
        step = SPEED_STEP if action == "faster" else -SPEED_STEP
        keys.percent = max(SPEED_STEP, min(100, keys.percent + step))
        console.print(f"speed {keys.percent}%")
        return False
    if action == "stop":
        drive.set(linear=0.0, angular=0.0)
        console.print("stop")
        return False
    linear, angular = keys.velocity(action)
    drive.set(linear=linear, angular=angular)
    console.print(f"{action} {keys.percent}%")
    return True


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

    keys = _Keys(robot, percent)
    loop.add_reader(fd, readable)
    try:
        async with robot.drive(rate=DRIVE_RATE) as drive:
            pending = b""
            held = False
            while True:
                try:
                    # A held key repeats; none for RELEASE_AFTER s means it was released.
                    chunk = await asyncio.wait_for(chunks.get(), RELEASE_AFTER if held else None)
                except asyncio.TimeoutError:
                    drive.set(linear=0.0, angular=0.0)
                    out_console().print("released: stop")
                    held = False
                    continue
                if not chunk:
                    return
                actions, pending = parse_keys(pending + chunk)
                for action in actions:
                    if action == "quit":
                        return
                    held = _apply(drive, keys, action) or (held and action in _KEEP)
    finally:
        loop.remove_reader(fd)


#: Keys that leave a held direction held.
_KEEP = ("faster", "slower")


def teleop(
    ctx: typer.Context,
    speed: Annotated[int, typer.Option(min=1, max=100, help="Start speed, % of max.")] = 30,
) -> None:
    """Drive with the keyboard (arrows or WASD) while a key is held; space stops, q quits.

    The speed is kept alive while the key repeats; released (no repeat for 0.5 s) it
    stops; a stop is written on every way out.
    """
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
                # Teleop and planner speeds override each other (docs/protocol.md §2.e).
                await robot.cancel()
                err_console().print("cancelled the running goal to take over")
            err_console().print(HELP)
            await _drive(robot, fd, speed)  # its drive block writes a stop on every exit
            out_console().print("stop (on exit)")
        finally:
            with contextlib.suppress(termios.error):  # a terminal that hung up (SIGHUP)
                termios.tcsetattr(fd, termios.TCSADRAIN, saved)
        return 0

    run_robot(settings, body, interrupted=ExitCode.OK, moving=True)
