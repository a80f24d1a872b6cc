"""A mission run's progress events: each step's start and end, each loop turn, the end."""

from __future__ import annotations

import asyncio
from collections import deque
from dataclasses import asdict, dataclass, field
from typing import Any

from .report import MissionReport, StepReport

__all__ = [
    "DEFAULT_EVENT_QUEUE",
    "LoopStarted",
    "MissionEnded",
    "MissionEvent",
    "MissionEventStream",
    "StepEnded",
    "StepStarted",
    "mission_events",
]

#: Events a MissionEventStream keeps for a slow reader (the oldest are dropped beyond).
DEFAULT_EVENT_QUEUE = 1000


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


class MissionEventStream:
    """Pass it as ``on_progress``; ``async for event in it`` gets each event, in order.

    Iteration ends after MissionEnded. A reader that falls ``maxlen`` events behind loses
    the oldest (``dropped`` counts them); the run never waits for it.
    """

    def __init__(self, maxlen: int = DEFAULT_EVENT_QUEUE) -> None:
        self._queue: deque[MissionEvent] = deque(maxlen=maxlen)
        self._ready = asyncio.Event()
        self._ended = False
        self.dropped = 0

    def __call__(self, event: MissionEvent) -> None:
        if len(self._queue) == self._queue.maxlen:
            self.dropped += 1
        self._queue.append(event)
        self._ready.set()

    def __aiter__(self) -> MissionEventStream:
        return self

    async def __anext__(self) -> MissionEvent:
        while not self._queue:
            if self._ended:
                raise StopAsyncIteration
            self._ready.clear()
            await self._ready.wait()
        event = self._queue.popleft()
        if isinstance(event, MissionEnded):
            self._ended = True
        return event


def mission_events(maxlen: int = DEFAULT_EVENT_QUEUE) -> MissionEventStream:
    """A MissionEventStream: ``run_mission(…, on_progress=stream)``, ``async for e in stream``."""
    return MissionEventStream(maxlen)
