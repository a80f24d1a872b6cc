"""The event loop the driver runs on (asyncio's, or a clear error), deadlines and cleanup on it."""

from __future__ import annotations

import asyncio
import enum
import logging
import sys
from typing import Any, Final, TypeVar

import anyio
import anyio.lowlevel

from ..errors import AsyncioRequired

__all__ = [
    "CLEANUP_TIMEOUT",
    "OPEN_ROBOTS",
    "ROBOT_DEFAULT",
    "Deadline",
    "RobotDefault",
    "finish_shielded",
    "or_default",
    "running_loop",
]

#: Every Robot not yet closed (galileo_async.testing reports the ones a test left open).
#: Held strongly: a Robot dropped unclosed would otherwise vanish with its link still open.
OPEN_ROBOTS: set[Any] = set()

_log = logging.getLogger(__name__)

#: Longest a caller waits for a cleanup (close) it cannot cancel; its steps bound themselves.
CLEANUP_TIMEOUT = 8.0

_T = TypeVar("_T")


def running_loop(what: str) -> asyncio.AbstractEventLoop:
    """The running asyncio loop; AsyncioRequired (naming ``what``) when none runs here."""
    try:
        return asyncio.get_running_loop()
    except RuntimeError:
        pass
    raise AsyncioRequired(
        f"{what}: the driver runs on asyncio, but {_running_library()}; run it under "
        "asyncio (asyncio.run, or anyio.run(..., backend='asyncio'))"
    ) from None


def _running_library() -> str:
    """What runs instead of asyncio, as far as can be told without importing anything."""
    trio = sys.modules.get("trio")
    if trio is not None:
        try:
            trio.lowlevel.current_task()
        except RuntimeError:
            pass
        else:
            return "this code runs under trio"
    return "no asyncio event loop is running in this thread"


class RobotDefault(enum.Enum):
    """The type of ROBOT_DEFAULT: an argument left out, so the Robot's own setting applies."""

    ROBOT_DEFAULT = "ROBOT_DEFAULT"

    def __repr__(self) -> str:
        return self.value


#: A timeout left out: the Robot's ``goal_timeout`` or ``wait_timeout`` applies (None: no limit).
ROBOT_DEFAULT: Final = RobotDefault.ROBOT_DEFAULT


def or_default(value: _T | RobotDefault, default: _T) -> _T:
    """``default`` when ``value`` is ROBOT_DEFAULT, else ``value``."""
    return default if isinstance(value, RobotDefault) else value


async def finish_shielded(task: asyncio.Task[None], what: str) -> None:
    """Wait for ``task`` (at most CLEANUP_TIMEOUT s) whatever cancels the caller, then re-raise.

    Neither asyncio's ``task.cancel()`` nor an anyio cancel scope interrupts the wait; the
    cancellation that arrived meanwhile is raised once ``task`` is done, so cleanup such as
    close() completes on every exit path and the caller still sees its cancellation.
    """
    loop = asyncio.get_running_loop()
    deadline = loop.time() + CLEANUP_TIMEOUT
    cancelled: asyncio.CancelledError | None = None
    # The anyio shield stops an anyio scope from cancelling the wait again and again; the
    # loop absorbs asyncio cancellations (task.cancel(), asyncio.timeout).
    with anyio.CancelScope(shield=True):
        while not task.done():
            remaining = deadline - loop.time()
            if remaining <= 0:
                _log.warning("%s did not finish within %s s", what, CLEANUP_TIMEOUT)
                break
            try:
                await asyncio.wait((task,), timeout=remaining)
            except asyncio.CancelledError as exc:
                cancelled = exc
    if task.done() and not task.cancelled() and task.exception() is not None:
        if cancelled is None:
            task.result()  # raises the cleanup's own error
        _log.warning("%s failed: %r", what, task.exception())
    if cancelled is not None:
        raise cancelled
    # An anyio scope cancelled meanwhile raises here, as its next checkpoint would.
    await anyio.lowlevel.checkpoint_if_cancelled()


class Deadline:
    """An absolute point in loop time, or none (wait for ever)."""

    __slots__ = ("at", "start", "timeout")

    def __init__(self, timeout: float | None) -> None:
        self.start = asyncio.get_running_loop().time()
        self.timeout = timeout
        self.at = None if timeout is None else self.start + timeout

    def remaining(self) -> float | None:
        """Seconds left (never negative), or None without a deadline."""
        if self.at is None:
            return None
        return max(0.0, self.at - asyncio.get_running_loop().time())

    def elapsed(self) -> float:
        """Seconds since the deadline was set."""
        return asyncio.get_running_loop().time() - self.start
