"""What a mission run did: each step's ending, attempts, times and distance (JSON-able)."""

from __future__ import annotations

from datetime import datetime
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field

__all__ = ["MissionEnding", "MissionRejected", "MissionReport", "StepEnding", "StepReport"]

#: How a step ended; a goal's are the goal endings' names (GoalChange, the errors).
StepEnding = Literal[
    "reached",  # a goal arrived (GoalResult)
    "done",  # any other step did what it says
    "aborted",  # GoalAborted: the planner gave up short of the target
    "rejected",  # GoalRejected or AcceptTimeout: the robot refused or never took the goal
    "stalled",  # GoalStalled: no progress for progress_timeout
    "timeout",  # the step's timeout (a goal's OperationTimeout)
    "failed",  # any other error (a call-out's answer, NotReady, a charging error …)
    "skipped",  # failed, and its policy skipped it
    "cancelled",  # the runner's task was cancelled mid-step
    "stopped",  # a user stop (stop(), cancel(), another host's cancel or goal) ended it
    "link lost",  # the link was lost mid-step
]
#: How a mission ended.
MissionEnding = Literal["completed", "stopped", "cancelled", "failed", "link lost"]


class MissionRejected(ValueError):
    """The mission cannot start (nothing moved): one line per problem in ``problems``."""

    def __init__(self, mission: str, problems: list[str]) -> None:
        super().__init__(f"mission {mission!r} rejected: " + "; ".join(problems))
        self.mission = mission
        self.problems = problems


class StepReport(BaseModel):
    """One run of one step: ``started``/``ended`` in loop seconds, ``*_at`` wall clock (UTC)."""

    model_config = ConfigDict(frozen=True)

    path: str = Field(description='where the step is: "steps[2].loop.steps[0]"')
    name: str | None
    action: str
    ending: StepEnding
    started: float
    ended: float
    started_at: datetime
    ended_at: datetime
    attempts: int = Field(ge=1)
    distance_m: float = Field(ge=0, description="driven while the step ran, from the poses")
    loops: dict[str, int] = Field(
        default_factory=dict, description="iteration (from 1) of each loop the step is in"
    )
    error: str | None = None

    @property
    def duration(self) -> float:
        """Seconds of loop time the step took."""
        return self.ended - self.started


class MissionReport(BaseModel):
    """A mission's run: its ending, every step run in order, the loops done."""

    model_config = ConfigDict(frozen=True)

    mission: str
    ending: MissionEnding
    steps: list[StepReport]
    started: float
    ended: float
    started_at: datetime
    ended_at: datetime
    loops_done: int = Field(0, description="loop iterations completed")
    stopped_by: str | None = Field(None, description='the user stop that ended it: "stop()" …')
    error: str | None = None
    resumed_at: str | None = Field(None, description="the step path a resume started at")

    @property
    def completed(self) -> bool:
        """True when every step ran (skipped ones included) and the mission ended normally."""
        return self.ending == "completed"

    @property
    def distance_m(self) -> float:
        """Metres driven over the whole run."""
        return sum(step.distance_m for step in self.steps)
