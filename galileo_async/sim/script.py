"""Scripted faults and overrides of the simulated robot (tests script the robot's answers)."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

from .._checks import check_int, check_names, check_number
from .states import EPSILON, FREE

#: Status values in WIRE_FIELDS order (robot_model.WireValues).
_Values = tuple[Any, ...]

__all__ = ["SETTABLE_FIELDS", "Scripting"]

#: Status fields ``set_fields`` takes, with their type: the others follow from the model
#: (speeds from motion, busy_status from busy(), angle_goal_status from the goal on real
#: firmware).
SETTABLE_FIELDS: dict[str, type] = {
    "nav_status": int,
    "visual_status": int,
    "map_status": int,
    "charge_status": int,
    "loop_status": int,
    "power": float,
    "target_num_id": int,
    "target_status": int,
    "target_distance": float,
    "x": float,
    "y": float,
    "theta": float,
}


class Scripting:
    """RobotModel's fault injection and overrides (a mixin: the state is RobotModel's)."""

    if TYPE_CHECKING:  # declared for the type checker only: the model defines them
        time: float
        busy_until: float
        nav_status: int
        target_status: int
        target_num_id: int
        visual_status: int
        x: float
        y: float
        theta: float
        _abort_next: bool
        _reject_next: bool
        _visual_lost_until: float | None
        _visual_ready_at: float | None
        _frozen: _Values | None
        _last_start: float | None

        def wire_values(self) -> _Values: ...
        def halt(self) -> None: ...

    def open_navigation(self) -> None:
        """Navigation open and tracking, no goal shown (free, id -1), nothing busy.

        As on a robot in service: its goal status left free by the last goal or cancel,
        so a refused goal shows as -1 (docs/protocol.md §2.b).
        """
        self.nav_status, self.visual_status = 1, 1
        self.target_status, self.target_num_id = FREE, -1
        self._visual_ready_at = None

    def lock_out_start(self) -> None:
        """Begin the firmware's start lockout now, as a start a moment ago would.

        A navigation start within ``start_ignore_time`` (5-30 s on real robots) is ignored
        (docs/protocol.md §2.a).
        """
        self._last_start = self.time

    def abort_next_goal(self) -> None:
        """Make the planner give up half way on the next goal (fault injection)."""
        self._abort_next = True

    def reject_next_goal(self) -> None:
        """Refuse the next goal as the firmware refuses an unknown target id."""
        self._reject_next = True

    def take_rejection(self) -> bool:
        """True once after reject_next_goal(): the goal starting now is refused."""
        rejected, self._reject_next = self._reject_next, False
        return rejected

    def set_busy(self, seconds: float) -> None:
        """Be busy for ``seconds`` from now (at least)."""
        self.busy_until = max(self.busy_until, self.time + seconds)

    def hold_busy(self, seconds: float) -> None:
        """Be busy for exactly ``seconds`` from now; 0 ends busy now (fault injection)."""
        self.busy_until = self.time + seconds

    def lose_visual(self, seconds: float | None = None) -> None:
        """Lose visual tracking (visual_status 2, the robot halts) for ``seconds`` or until set."""
        self.visual_status = 2
        self._visual_ready_at = None
        self._visual_lost_until = None if seconds is None else self.time + seconds
        self.halt()

    def step_script(self) -> None:
        """Per step: tracking comes back when a timed lose_visual() ends."""
        until = self._visual_lost_until
        if until is not None and self.time + EPSILON >= until:
            self._visual_lost_until = None
            if self.visual_status == 2:
                self.visual_status = 1

    def freeze(self) -> None:
        """The navigation stack dies: the same status re-sent, commands without effect."""
        if self._frozen is None:
            self._frozen = self.wire_values()

    def thaw(self) -> None:
        """The navigation stack comes back where it stopped."""
        self._frozen = None

    def place(self, x: float, y: float, theta: float) -> None:
        """Put the robot at (x, y) facing ``theta`` radians, at rest."""
        x, y, theta = check_number("x", x), check_number("y", y), check_number("heading", theta)
        self.x, self.y = x, y  # all checked first: a bad heading changes nothing
        self.theta = math.remainder(theta, math.tau)
        self.halt()

    def set_fields(self, **values: Any) -> None:
        """Override status fields (SETTABLE_FIELDS); all are checked before any is set."""
        check_names(values, SETTABLE_FIELDS)
        checked = {
            name: check_int(name, value, -(2**31), 2**31 - 1)
            if SETTABLE_FIELDS[name] is int
            else check_number(name, value)
            for name, value in values.items()
        }
        for name, value in checked.items():
            setattr(self, name, value)
        if "visual_status" in values:  # an explicit visual state ends the scripted ones
            self._visual_lost_until = self._visual_ready_at = None
