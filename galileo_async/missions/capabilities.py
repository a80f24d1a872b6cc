"""What each step needs to run: of the robot's link (the steps a link cannot run), and of
the caller (the wait steps' releases)."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from .model import Mission, WaitStep, step_action, step_paths

if TYPE_CHECKING:
    from .robot_api import MissionRobot

__all__ = [
    "HTTP_ONLY",
    "REST_API",
    "Unsupported",
    "capabilities_of",
    "needs",
    "unreleased",
    "unsupported",
]

#: The capability of a link that speaks the robot's HTTP API (http://, https://).
REST_API = "rest_api"
#: The step kinds only the HTTP API can run (docs/protocol.md §5.3).
HTTP_ONLY = frozenset({"goto_pose", "say", "switch_map"})


@dataclass(frozen=True)
class Unsupported:
    """A step (by path and name) the link cannot run, and the capabilities it lacks."""

    path: str
    name: str | None
    action: str
    missing: frozenset[str]

    @property
    def reason(self) -> str:
        """What the step needs, without where it is: ``say needs an http:// … link``."""
        return f"{self.action} needs an http:// or https:// link"

    def __str__(self) -> str:
        where = self.path if self.name is None else f"{self.path} ({self.name})"
        return f"{where}: {self.reason}"


def needs(step: Any) -> frozenset[str]:
    """The link capabilities ``step`` needs (empty: every link runs it)."""
    return frozenset({REST_API}) if step_action(step) in HTTP_ONLY else frozenset()


def capabilities_of(robot: MissionRobot) -> frozenset[str]:
    """The capabilities of ``robot``'s link that steps need."""
    return frozenset({REST_API}) if robot.http is not None else frozenset()


def unsupported(mission: Mission, capabilities: Iterable[str]) -> list[Unsupported]:
    """Every step of ``mission`` (loops' included) a link with ``capabilities`` cannot run."""
    have = frozenset(capabilities)
    found = []
    for path, step in step_paths(mission.steps):
        missing = needs(step) - have
        if missing:
            found.append(Unsupported(path, step.name, step_action(step) or "?", missing))
    return found


def unreleased(mission: Mission, releases: Iterable[str]) -> list[tuple[str, WaitStep]]:
    """Every wait step of ``mission`` (path, step) whose release is not in ``releases``."""
    given = frozenset(releases)
    return [
        (path, step)
        for path, step in step_paths(mission.steps)
        if isinstance(step, WaitStep) and step.wait.release not in given
    ]
