"""Running a goal from the terminal: live distance on stderr, a result line, an exit code."""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import AsyncIterator, Awaitable, Callable
from typing import TYPE_CHECKING, Any, TypeVar

from rich.live import Live
from rich.text import Text

from ..errors import GalileoTimeout, GoalError
from ..models import GalileoStatus
from .render import goal_line, status_line
from .runner import (
    ExitCode,
    Settings,
    err_console,
    exit_code_for,
    out_console,
    print_json,
    report,
)

if TYPE_CHECKING:
    from ..robot import GoalResult, Robot

__all__ = ["aclose", "follow_goal", "with_progress"]

T = TypeVar("T")

#: Result names in --json output, by exit code.
RESULT_NAMES = {
    ExitCode.OK: "arrived",
    ExitCode.REJECTED: "rejected",
    ExitCode.ABORTED: "aborted",
    ExitCode.CANCELLED: "cancelled",
    ExitCode.TIMEOUT: "timeout",
}


async def aclose(iterator: AsyncIterator[Any]) -> None:
    """Close an async iterator that has ``aclose`` (async generators do)."""
    closer = getattr(iterator, "aclose", None)
    if closer is not None:
        await closer()


async def _show(robot: Robot, label: str, live: Live, line: Callable[[GalileoStatus], str]) -> None:
    loop = asyncio.get_running_loop()
    start = loop.time()
    stream = robot.statuses()
    try:
        async for status in stream:
            elapsed = loop.time() - start
            live.update(Text(f"{label} · {elapsed:5.1f} s · {line(status)}"))
    finally:
        await aclose(stream)


async def with_progress(
    robot: Robot,
    label: str,
    operation: Awaitable[T],
    *,
    show: bool,
    line: Callable[[GalileoStatus], str] = status_line,
) -> T:
    """Await ``operation`` while a live line on stderr shows the robot's progress."""
    if not show:
        return await operation
    with Live(Text(label), console=err_console(), transient=True, refresh_per_second=10) as live:
        watcher = asyncio.ensure_future(_show(robot, label, live, line))
        try:
            return await operation
        finally:
            watcher.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await watcher


async def follow_goal(
    settings: Settings,
    robot: Robot,
    label: str,
    start: Callable[[], Awaitable[GoalResult]],
) -> int:
    """Run a goal with progress; print the result (or --json); return its exit code."""
    try:
        result = await with_progress(robot, label, start(), show=not settings.json, line=goal_line)
    except (GoalError, GalileoTimeout) as exc:
        code = exit_code_for(exc)
        if settings.json:
            payload = {
                "result": RESULT_NAMES.get(code, "error"),
                "target_id": getattr(exc, "target_id", None),
                "distance": getattr(exc, "distance", None),
                "error": str(exc),
            }
            print_json(settings, payload)
        else:
            report(exc, settings.verbose)
        return int(code)
    if settings.json:
        payload = {
            "result": "arrived",
            "target_id": result.target_id,
            "distance": None if result.distance is None else round(result.distance, 3),
            "elapsed": round(result.elapsed, 3),
            "already_there": result.already_there,
        }
        print_json(settings, payload)
    else:
        there = " (it was already there)" if result.already_there else ""
        out_console().print(
            f"arrived at target {result.target_id}: {result.distance or 0.0:.2f} m from it "
            f"after {result.elapsed:.1f} s{there}"
        )
    return int(ExitCode.OK)
