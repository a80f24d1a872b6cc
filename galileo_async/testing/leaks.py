"""LeakCheck: what a test left behind on its event loop (open Robots, tasks, timers)."""

from __future__ import annotations

import asyncio
from typing import Any

from ..robot.runtime import OPEN_ROBOTS

__all__ = ["LeakCheck"]

#: Loop turns given to tasks that are already finishing before anything counts as left.
_SETTLE_TURNS = 3


def _armed_timers(loop: asyncio.AbstractEventLoop) -> set[asyncio.TimerHandle]:
    # The loop keeps its timers in a private heap: only this check reads it.
    scheduled: list[asyncio.TimerHandle] = getattr(loop, "_scheduled", [])
    return {handle for handle in scheduled if not handle.cancelled()}


class LeakCheck:
    """A snapshot of the running loop; ``await finish()`` cleans up and names what was left."""

    def __init__(self) -> None:
        self._loop = asyncio.get_running_loop()
        self._tasks = asyncio.all_tasks(self._loop)
        self._timers = _armed_timers(self._loop)
        self._robots = set(OPEN_ROBOTS)

    async def finish(self) -> list[str]:
        """Close, cancel and disarm what appeared since the snapshot; one line per kind left."""
        for _ in range(_SETTLE_TURNS):
            await asyncio.sleep(0)
        problems: list[str] = []
        robots = [robot for robot in list(OPEN_ROBOTS) if robot not in self._robots]
        for robot in robots:
            await robot.close()
        if robots:
            names = ", ".join(repr(robot) for robot in robots)
            problems.append(f"{len(robots)} Robot(s) left open: {names}")
        current = asyncio.current_task()
        tasks = [
            task
            for task in asyncio.all_tasks(self._loop) - self._tasks - {current}
            if not task.done()
        ]
        for task in tasks:
            task.cancel()
        if tasks:
            await asyncio.gather(*tasks, return_exceptions=True)
            problems.append(f"{len(tasks)} task(s) left running: {_names(tasks)}")
        timers = _armed_timers(self._loop) - self._timers
        described = sorted(map(repr, timers))  # before cancel(): a cancelled one hides its callback
        for timer in timers:
            timer.cancel()
        if timers:
            problems.append(f"{len(timers)} timer(s) left armed: {described}")
        return problems


def _names(tasks: list[asyncio.Task[Any]]) -> str:
    return ", ".join(sorted(f"{task.get_name()} ({task.get_coro()!r})" for task in tasks))
