"""Missions on many robots at once; the first user stop stops them all."""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Callable, Mapping

import anyio

from ..robot.runtime import finish_shielded
from .events import MissionEvent
from .model import Mission
from .report import MissionRejected, MissionReport
from .robot_api import MissionRobot, StopAll
from .runner import Releases, _Run

__all__ = ["run_missions"]

_log = logging.getLogger(__name__)

#: Mission endings that stop every other robot of the fleet.
_STOPS_ALL = frozenset({"stopped", "cancelled"})


async def run_missions(
    robots: Mapping[str, MissionRobot],
    missions: Mapping[str, Mission],
    *,
    stop_all: StopAll,
    releases: Releases | None = None,
    on_progress: Callable[[str, MissionEvent], None] | None = None,
) -> dict[str, MissionReport]:
    """Run ``missions[name]`` on ``robots[name]``, all at once; the reports by name.

    Every mission is checked before any robot moves (MissionRejected naming each robot's
    problems). A mission that ends stopped (a user stop on its robot) calls ``stop_all``,
    which stops every robot, so every mission ends stopped too. Cancelling the call
    cancels every run, each robot stopped on the way out.
    """
    runs: dict[str, _Run] = {}
    problems: list[str] = []
    for name, mission in missions.items():
        progress = None if on_progress is None else _tagged(on_progress, name)
        run = _Run(robots[name], mission, dict(releases or {}), progress, None)
        try:
            run.check(None, resume=False, max_age=0.0)
        except MissionRejected as exc:
            problems.extend(f"{name}: {problem}" for problem in exc.problems)
        runs[name] = run
    if problems:
        names = ", ".join(sorted({mission.mission for mission in missions.values()}))
        raise MissionRejected(names, problems)
    reports: dict[str, MissionReport] = {}
    stopping: list[asyncio.Task[None]] = []

    async def stop_every_robot() -> None:
        try:
            await stop_all()
        except Exception:  # each robot's own exit stop still runs; say what failed
            _log.exception("stopping the fleet after a user stop failed")

    async def one(name: str) -> None:
        report = reports[name] = await runs[name].run(None)
        if report.ending in _STOPS_ALL and not stopping:
            stopping.append(asyncio.ensure_future(stop_every_robot()))

    try:
        async with anyio.create_task_group() as group:
            for name in runs:
                group.start_soon(one, name)
    finally:
        for stop in stopping:  # the other robots' stops complete, whatever cancels this
            await finish_shielded(stop, "stopping the fleet")
    return {name: reports[name] for name in runs}


def _tagged(
    on_progress: Callable[[str, MissionEvent], None], name: str
) -> Callable[[MissionEvent], None]:
    return lambda event: on_progress(name, event)
