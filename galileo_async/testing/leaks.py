"""LeakCheck: what a test left behind on its event loop (open Robots, tasks, timers)."""

from __future__ import annotations

import asyncio
from typing import Any

from ..robot.runtime import OPEN_ROBOTS

__all__ = ["LeakCheck"]

#: Loop turns given to tasks that are already finishing before anything counts as left.
_SETTLE_TURNS = 3
#: Modules whose tasks belong to an open link (its writer, its reconnect loop), fleet, or a
#: Robot's control socket (a request it runs).
_DRIVER_MODULES = (
    "galileo_async.transports", "galileo_async.http", "galileo_async.ros", "galileo_async.fleet",
    "galileo_async.robot.control_server",
)  # fmt: skip


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

    async def stop_tasks(self) -> list[str]:
        """Cancel the tasks started since the snapshot and still running, but links' and fleets'.

        For the end of a test body, before the Robots it used close (a task left running
        might otherwise end with ConnectionLost and go unnoticed).
        """
        await self._settle()
        current = asyncio.current_task()
        tasks = [
            task
            for task in asyncio.all_tasks(self._loop) - self._tasks - {current}
            if not task.done() and not _of_the_driver(task)
        ]
        return await self._cancel(tasks)

    async def finish(self) -> list[str]:
        """Close, cancel and disarm what appeared since the snapshot; one line per kind left."""
        await self._settle()
        problems: list[str] = []
        robots = [robot for robot in list(OPEN_ROBOTS) if robot not in self._robots]
        if robots:
            names = ", ".join(repr(robot) for robot in robots)
            problems.append(f"{len(robots)} Robot(s) left open: {names}")
        for robot in robots:
            await robot.close()
        current = asyncio.current_task()
        tasks = [
            task
            for task in asyncio.all_tasks(self._loop) - self._tasks - {current}
            if not task.done()
        ]
        problems += await self._cancel(tasks)
        timers = _armed_timers(self._loop) - self._timers
        if timers:  # described while armed: a cancelled handle forgets its callback
            problems.append(f"{len(timers)} timer(s) left armed: {sorted(map(repr, timers))}")
        for timer in timers:
            timer.cancel()
        return problems

    @staticmethod
    async def _settle() -> None:
        for _ in range(_SETTLE_TURNS):
            await asyncio.sleep(0)

    @staticmethod
    async def _cancel(tasks: list[asyncio.Task[Any]]) -> list[str]:
        for task in tasks:
            task.cancel()
        if not tasks:
            return []
        await asyncio.gather(*tasks, return_exceptions=True)
        return [f"{len(tasks)} task(s) left running: {_names(tasks)}"]


def _of_the_driver(task: asyncio.Task[Any]) -> bool:
    frame = getattr(task.get_coro(), "cr_frame", None)
    module = "" if frame is None else str(frame.f_globals.get("__name__", ""))
    return module.startswith(_DRIVER_MODULES)


def _names(tasks: list[asyncio.Task[Any]]) -> str:
    return ", ".join(sorted(f"{task.get_name()} ({task.get_coro()!r})" for task in tasks))
