"""Running a goal from the terminal: live distance on stderr, a result line, an exit code."""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections.abc import AsyncIterator, Awaitable, Callable
from typing import TYPE_CHECKING, Any, TypeVar

from rich.live import Live
from rich.text import Text

from ..errors import GalileoTimeout, GoalError
from ..models import GalileoStatus
from .render import goal_line, pose_text, rounded, status_line
from .runner import (
    ExitCode,
    Settings,
    err_console,
    exit_code_for,
    out_console,
    print_json,
    report,
)
from .signals import interruption, pose_json

if TYPE_CHECKING:
    from ..robot import GoalResult, Robot

__all__ = ["CLEAR_ERROR_TIMEOUT", "aclose", "clear_goal_error", "run_goal", "with_progress"]

T = TypeVar("T")
_log = logging.getLogger(__name__)

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


#: Seconds between plain progress lines when stderr is not a terminal (sooner on a change).
PLAIN_PROGRESS_PERIOD = 1.0


async def _show_plain(robot: Robot, label: str, line: Callable[[GalileoStatus], str]) -> None:
    """One progress line on stderr per PLAIN_PROGRESS_PERIOD, or at once when a state changes."""
    loop = asyncio.get_running_loop()
    start = loop.time()
    last_at = start  # a quick operation prints nothing
    last_states: object = None
    console = err_console()
    stream = robot.statuses()
    try:
        async for status in stream:
            now = loop.time()
            states = (status.nav_status, status.visual_status, status.target_status)
            changed = last_states is not None and states != last_states
            last_states = states
            if changed or now - last_at >= PLAIN_PROGRESS_PERIOD:
                last_at = now
                text = f"{label} · {now - start:5.1f} s · {line(status)}"
                console.print(text, markup=False, highlight=False)
                console.file.flush()
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
    """Await ``operation`` with progress on stderr: a live line on a terminal, else plain lines."""
    if not show:
        return await operation
    console = err_console()
    with contextlib.ExitStack() as stack:
        if console.is_terminal:
            live = Live(Text(label), console=console, transient=True, refresh_per_second=10)
            stack.enter_context(live)
            watcher = asyncio.ensure_future(_show(robot, label, live, line))
        else:
            watcher = asyncio.ensure_future(_show_plain(robot, label, line))
        try:
            return await operation
        finally:
            watcher.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await watcher


def _distance(robot: Robot, exc: BaseException | None = None) -> float | None:
    """The last distance to the target known (the error's, else the latest status's), rounded."""
    distance = getattr(exc, "distance", None)
    status = getattr(exc, "status", None) or robot.status
    if distance is None and status is not None and (status.target_distance or -1.0) >= 0:
        distance = status.target_distance
    return None if distance is None else rounded("target_distance", distance)


def _interrupted(robot: Robot, target_id: int | None, sent: int) -> None:
    """Note for the interrupted line what the goal left behind: whether cancel went out."""
    goal = "the goal" if target_id is None else f"goal {target_id}"
    what = f"{goal} cancelled (i 2 sent)" if sent > 0 else f"{goal} was not running, no cancel sent"
    note = interruption()
    note.done.append(what)
    note.where = pose_text(robot.status)
    note.fields.update(
        target_id=target_id,
        cancel_sent=sent > 0,
        distance=_distance(robot),
        pose=pose_json(robot.status),
    )


async def run_goal(
    settings: Settings,
    robot: Robot,
    label: str,
    start: Callable[[], Awaitable[GoalResult]],
    *,
    target_id: int | None = None,
    goal_commands: int = 1,
) -> int:
    """Run a goal with progress; print the result (or --json); return its exit code.

    ``goal_commands``: how many commands start the goal (any further one is the cancel
    that an interruption sends).
    """
    sent_before = robot.link.commands_sent
    try:
        result = await with_progress(robot, label, start(), show=not settings.json, line=goal_line)
    except asyncio.CancelledError:
        cancels = robot.link.commands_sent - sent_before - goal_commands
        _interrupted(robot, target_id, cancels)
        raise
    except (GoalError, GalileoTimeout) as exc:
        code = exit_code_for(exc)
        if settings.json:
            payload = {
                "result": RESULT_NAMES.get(code, "error"),
                "target_id": getattr(exc, "target_id", target_id),
                "distance": _distance(robot, exc),
                "error": str(exc),
                "exit_code": int(code),
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


#: Seconds to wait for a cancel to clear an earlier goal error before sending a goal.
CLEAR_ERROR_TIMEOUT = 1.0


async def clear_goal_error(robot: Robot) -> None:
    """Cancel an earlier goal error (-1) first, so that a rejection of the new id shows.

    Real firmware reports a bad id as -1 and leaves target_num_id alone (docs/protocol.md §2.b):
    with -1 already showing, a second rejection changes nothing on the wire. Its cancel
    (``i 2``) turns an error back to free.
    """
    status = robot.status
    if status is None or not status.goal_failed or not status.navigating:
        return
    _log.debug("cancel first: target_status %s hides a rejection", status.target_status)
    await robot.cancel()
    with contextlib.suppress(GalileoTimeout):
        await robot.wait_until(lambda s: not s.goal_failed, timeout=CLEAR_ERROR_TIMEOUT)
