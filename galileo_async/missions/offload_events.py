"""An offloaded mission's progress and report in the runner's shapes (events, MissionReport).

offload_mission reports what its follower saw of the chain (ChainProgress, OffloadReport);
OffloadEvents turns that into the events and the report a run on the host gives, so that
both print the same lines. A chain knows no distances (0 m) and no attempts (1 each).
"""

from __future__ import annotations

import asyncio
from datetime import datetime, timedelta, timezone

from .events import LoopStarted, MissionEnded, MissionEvent, StepEnded, StepStarted
from .model import LoopStep, Mission
from .offload import ActionRun, ChainProgress, OffloadReport
from .report import MissionReport, StepEnding, StepReport

__all__ = ["OffloadEvents"]

#: The steps whose success is "reached" (a goal), as the runner names them.
_GOALS = frozenset({"goto", "goto_point", "goto_pose"})
#: The step ending of an action's last state (COMPLETE: reached or done).
_ENDINGS: dict[str, StepEnding] = {"ERROR": "failed", "CANCELLED": "stopped"}


def _wall(at: float) -> datetime:
    """The wall-clock time (UTC) of loop time ``at``, from the loop's now."""
    return datetime.now(timezone.utc) - timedelta(seconds=asyncio.get_running_loop().time() - at)


class OffloadEvents:
    """The runner's events for one offloaded ``mission``; call it in its event loop."""

    def __init__(self, mission: Mission) -> None:
        self.mission = mission
        steps = mission.steps
        self.loop = steps[0] if len(steps) == 1 and isinstance(steps[0], LoopStep) else None
        self.passes = 0

    def of(self, progress: ChainProgress) -> list[MissionEvent]:
        """The events of one ChainProgress: a new pass's LoopStarted, then the step's."""
        run, found = progress.run, list[MissionEvent]()
        if self.loop is not None and run.loop > self.passes:
            self.passes = run.loop
            found.append(LoopStarted(
                self.mission.mission, progress.at, "steps[0]", self.loop.name, run.loop,
                self.loop.loop.count,
            ))  # fmt: skip
        if run.ended is None:
            found.append(StepStarted(
                self.mission.mission, progress.at, run.path, run.name, run.action, 1,
                self._loops(run),
            ))  # fmt: skip
        else:
            found.append(StepEnded(self.mission.mission, progress.at, self.step(run)))
        return found

    def _loops(self, run: ActionRun) -> dict[str, int]:
        return {} if self.loop is None else {"steps[0]": run.loop}

    def step(self, run: ActionRun) -> StepReport:
        """An action run that ended as the runner's StepReport."""
        ended = run.started if run.ended is None else run.ended
        ending = _ENDINGS.get(run.state) or ("reached" if run.action in _GOALS else "done")
        error = None if ending in ("reached", "done") else f"{run.type} ended {run.state}"
        return StepReport(
            path=run.path, name=run.name, action=run.action, ending=ending,
            started=run.started, ended=ended, started_at=_wall(run.started),
            ended_at=_wall(ended), attempts=1, distance_m=0.0, loops=self._loops(run),
            error=error,
        )  # fmt: skip

    def ended(self, report: OffloadReport) -> MissionEnded:
        """The MissionEnded event of the OffloadReport ``report``."""
        steps = [self.step(run) for run in report.actions if run.ended is not None]
        mission = MissionReport(
            mission=report.mission, ending=report.ending, steps=steps,
            started=report.started, ended=report.ended, started_at=_wall(report.started),
            ended_at=_wall(report.ended), loops_done=report.loops_done, error=report.error,
        )  # fmt: skip
        return MissionEnded(report.mission, report.ended, mission)
