"""A stand-in for missions.runner.run_mission: goto and dwell steps, loops, a journal."""

from __future__ import annotations

import asyncio
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import anyio

from galileo_async import Robot
from galileo_async.missions.model import DwellStep, GotoStep, LoopStep, Mission


@dataclass(frozen=True)
class StepStarted:
    """A step began (the runner's event of the same name)."""

    path: str
    action: str


@dataclass(frozen=True)
class StepEnded:
    """A step ended."""

    path: str
    action: str


@dataclass
class FakeRuns:
    """What the fake runner was asked: one (mission, resume, first step index) per call."""

    calls: list[tuple[str, bool, int]]
    #: The journal: the step each journal path's run was at (kept here, not in the file).
    journals: dict[Path, int] = field(default_factory=dict)


def _flat(steps: list[Any], prefix: str) -> Iterator[tuple[str, Any]]:
    for index, step in enumerate(steps):
        path = f"{prefix}[{index}]"
        if isinstance(step, LoopStep):
            count = 0
            while step.loop.count is None or count < step.loop.count:
                yield from _flat(step.loop.steps, f"{path}.loop.steps")
                count += 1
        else:
            yield path, step


def fake_runner(runs: FakeRuns) -> Callable[..., Any]:
    """A runner recording its calls in ``runs``; cancelled, it stops the robot (bounded)."""

    async def run(
        robot: Robot,
        mission: Mission,
        *,
        journal: Path,
        resume: bool = False,
        on_progress: Callable[[object], None] | None = None,
    ) -> dict[str, str]:
        first = runs.journals.get(journal, 0) if resume else 0
        runs.calls.append((mission.mission, resume, first))
        emit = on_progress or (lambda event: None)
        try:
            for number, (path, step) in enumerate(_flat(mission.steps, "steps")):
                if number < first:
                    continue
                runs.journals[journal] = number
                action = "goto" if isinstance(step, GotoStep) else "dwell"
                emit(StepStarted(path, action))
                if isinstance(step, GotoStep):
                    await robot.goto(step.goto)
                elif isinstance(step, DwellStep):
                    await asyncio.sleep(step.dwell)
                emit(StepEnded(path, action))
            return {"ending": "completed"}
        except BaseException:
            with anyio.CancelScope(shield=True), anyio.move_on_after(5):
                await robot.stop()
            raise

    return run
