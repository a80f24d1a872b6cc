"""play_mission(): a mission on a simulated robot, faults at chosen seconds, its timeline."""

from __future__ import annotations

import asyncio
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import anyio

from ..missions.events import LoopStarted, MissionEnded, MissionEvent, StepEnded, StepStarted
from ..missions.model import Mission
from ..missions.report import MissionReport
from ..missions.runner import run_mission
from ..robot import Robot

__all__ = ["MissionPlay", "play_mission"]


@dataclass
class MissionPlay:
    """A played mission: its report, every progress event, and when it started (loop time)."""

    report: MissionReport
    events: list[MissionEvent] = field(default_factory=list)
    started: float = 0.0

    def timeline(self) -> list[str]:
        """One line per event: seconds since the start, what happened."""
        lines = []
        for event in self.events:
            at = f"{event.at - self.started:9.1f} s  "
            if isinstance(event, StepStarted):
                what = f"{event.path} {event.action} started (attempt {event.attempt})"
            elif isinstance(event, StepEnded):
                step = event.step
                error = f": {step.error}" if step.error else ""
                what = f"{step.path} {step.action} {step.ending}{error}"
            elif isinstance(event, LoopStarted):
                count = "forever" if event.count is None else f"of {event.count}"
                what = f"{event.path} loop {event.iteration} {count}"
            else:
                assert isinstance(event, MissionEnded)
                what = f"mission {event.report.ending}"
            lines.append(at + what)
        return lines


async def play_mission(
    robot: Robot,
    mission: Mission,
    *,
    faults: Mapping[float, Callable[[], object]] | None = None,
    **options: Any,
) -> MissionPlay:
    """Run ``mission`` on ``robot``, calling each of ``faults`` at its second of the run.

    ``faults``: seconds after the start → a function to call then (e.g. a
    SimulatedDevice's ``go_charge``, ``abort_next_goal``, ``drop_link``); on the virtual
    clock the seconds are virtual. ``options`` go to run_mission. Faults not yet due when
    the mission ends are not called.
    """
    loop = asyncio.get_running_loop()
    events: list[MissionEvent] = []
    started = loop.time()

    async def script() -> None:
        for at, fault in sorted((faults or {}).items(), key=lambda item: item[0]):
            await anyio.sleep(max(0.0, started + at - loop.time()))
            fault()

    faulting = asyncio.ensure_future(script())
    try:
        report = await run_mission(robot, mission, on_progress=events.append, **options)
    finally:
        faulting.cancel()
        await asyncio.wait((faulting,))
        if not faulting.cancelled() and faulting.exception() is not None:
            faulting.result()  # a fault that raised is the test's error
    return MissionPlay(report, events, started)
