"""StopReport: what Robot.stop() found moving and stopped."""

from __future__ import annotations

from dataclasses import dataclass

from ..models import GalileoStatus

__all__ = ["DEFAULT_STOP_TIMEOUT", "StopReport"]

#: Seconds stop() waits for the status to show the robot stopped (goal, patrol, speed).
DEFAULT_STOP_TIMEOUT = 5.0


@dataclass(frozen=True, slots=True)
class StopReport:
    """What stop() stopped; every part is confirmed by ``status`` (None: no status seen).

    ``goal``: the id of the goal that was working or paused and was cancelled (None: none).
    ``patrol``: a patrol was running and was stopped. ``drive``: a drive() or turn_to()
    session of this Robot was ended. ``task``: the id of the HTTP nav task stopped
    (http:// only). ``moving``: the status showed a speed when stop() was called.
    """

    goal: int | None = None
    patrol: bool = False
    drive: bool = False
    task: str | None = None
    moving: bool = False
    status: GalileoStatus | None = None

    @property
    def stopped(self) -> tuple[str, ...]:
        """What was stopped, in words ("goal 3 cancelled", "patrol stopped", …); may be empty."""
        parts: list[str] = []
        if self.goal is not None:
            parts.append(f"goal {self.goal} cancelled")
        if self.task is not None:
            parts.append(f"task {self.task} stopped")
        if self.patrol:
            parts.append("patrol stopped")
        if self.drive:
            parts.append("drive ended")
        if self.moving:
            parts.append("speed zeroed")
        return tuple(parts)

    def __str__(self) -> str:
        return ", ".join(self.stopped) or "nothing was moving"
