"""The part of the Robot's public API a mission uses, as a Protocol.

Robot.run_mission and Fleet.run_missions load the runner inside the call, so the runner
names the Robot by what it uses, not by importing its module: no import circle between
the Robot and the missions above it (tests/packaging/test_import_graph.py).
"""

from __future__ import annotations

from collections.abc import Awaitable, Callable
from typing import TYPE_CHECKING, Protocol

from ..models import ChargeStatus, GalileoStatus, LinkState

if TYPE_CHECKING:
    from ..robot.drive import DriveSession, SpeedLimits
    from ..robot.goal import GoalResult
    from ..robot.http_part import HttpPart
    from ..robot.runtime import RobotDefault
    from ..robot.stopping import StopReport

__all__ = ["MissionRobot", "StopAll"]

#: Stops every robot of a fleet (Fleet.stop).
StopAll = Callable[[], Awaitable[object]]


class MissionRobot(Protocol):
    """What run_mission and check_mission use of a Robot (galileo_async.Robot is one)."""

    http: HttpPart | None
    speed_limits: SpeedLimits

    @property
    def status(self) -> GalileoStatus | None:
        """The latest status."""

    @property
    def map_targets(self) -> int | None:
        """The number of targets in the robot's map (None: not known)."""

    @property
    def closed(self) -> bool:
        """True once close() was called."""

    @property
    def link_state(self) -> LinkState:
        """The link's state."""

    def add_stop_listener(self, listener: Callable[[str], None]) -> None:
        """Call ``listener`` after every user stop."""

    def remove_stop_listener(self, listener: Callable[[str], None]) -> None:
        """Undo add_stop_listener."""

    def add_update_listener(self, listener: Callable[[GalileoStatus], None]) -> None:
        """Call ``listener`` with every status."""

    def remove_update_listener(self, listener: Callable[[GalileoStatus], None]) -> None:
        """Undo add_update_listener."""

    async def wait_until(
        self,
        predicate: Callable[[GalileoStatus], bool],
        timeout: float | RobotDefault | None = ...,
    ) -> GalileoStatus:
        """The first status where ``predicate`` holds."""

    async def wait_link(
        self, *states: LinkState, timeout: float | RobotDefault | None = ...
    ) -> LinkState:
        """The first of ``states`` the link is in."""

    async def goto(
        self, target_id: int, *, timeout: float | RobotDefault | None = ...
    ) -> GoalResult:
        """Go to a map target."""

    async def goto_point(
        self, x: float, y: float, *, timeout: float | RobotDefault | None = ...
    ) -> GoalResult:
        """Go to a point."""

    async def start_navigation(self, *, timeout: float | None = ...) -> None:
        """Open navigation."""

    async def start_charging(self, *, timeout: float | None = ...) -> ChargeStatus:
        """Dock and charge."""

    async def turn_to(self, degrees: float, *, timeout: float | None = ...) -> None:
        """Turn in place."""

    def drive(self, linear: float = ..., angular: float = ...) -> DriveSession:
        """A velocity session."""

    async def stop(self, brake: int = ..., *, timeout: float | None = ...) -> StopReport:
        """Halt every motion."""
