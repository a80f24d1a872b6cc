"""A mission run's progress events: each step's start and end, each loop turn, the end."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any

from .report import MissionReport, StepReport

__all__ = ["LoopStarted", "MissionEnded", "MissionEvent", "StepEnded", "StepStarted"]


@dataclass(frozen=True)
class MissionEvent:
    """Base of the progress events; ``at`` is loop time (seconds)."""

    mission: str
    at: float

    @property
    def kind(self) -> str:
        """The event's name in JSON lines ("step_started" …)."""
        return _KINDS[type(self)]

    def to_json(self) -> dict[str, Any]:
        """A JSON-able dict: ``event`` (the kind) and the fields."""
        return {"event": self.kind, **asdict(self)}


@dataclass(frozen=True)
class StepStarted(MissionEvent):
    """A step begins an attempt (``attempt`` from 1)."""

    path: str
    name: str | None
    action: str
    attempt: int
    loops: dict[str, int] = field(default_factory=dict)


@dataclass(frozen=True)
class StepEnded(MissionEvent):
    """A step ended (after its retries): its report."""

    step: StepReport

    def to_json(self) -> dict[str, Any]:
        """As MissionEvent's, the step's report as JSON."""
        return {"event": self.kind, "mission": self.mission, "at": self.at,
                "step": self.step.model_dump(mode="json")}  # fmt: skip


@dataclass(frozen=True)
class LoopStarted(MissionEvent):
    """A loop begins its ``iteration`` (from 1) of ``count`` (None: forever)."""

    path: str
    name: str | None
    iteration: int
    count: int | None


@dataclass(frozen=True)
class MissionEnded(MissionEvent):
    """The mission ended: its report."""

    report: MissionReport

    def to_json(self) -> dict[str, Any]:
        """As MissionEvent's, the report as JSON without the steps (StepEnded had them)."""
        report = self.report.model_dump(mode="json", exclude={"steps"})
        return {"event": self.kind, "mission": self.mission, "at": self.at, "report": report}


_KINDS: dict[type[MissionEvent], str] = {
    StepStarted: "step_started",
    StepEnded: "step_ended",
    LoopStarted: "loop_started",
    MissionEnded: "mission_ended",
}
