"""Patrol, mapping, charging and the other commands of the simulated robot that are not goals."""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..protocol import commands as cmd
from .states import ACTIVE, CHARGE_FREE, CHARGED, CHARGING, EPSILON, FINDING

if TYPE_CHECKING:
    from .config import SimConfig

__all__ = ["ServiceCommands"]


class ServiceCommands:
    """RobotModel's handlers of these commands (a mixin: the state is RobotModel's)."""

    if TYPE_CHECKING:  # declared for the type checker only: the model defines them
        config: SimConfig
        time: float
        x: float
        y: float
        control_v: float
        control_w: float
        nav_status: int
        visual_status: int
        map_status: int
        charge_status: int
        loop_status: int
        target_status: int
        patrol_dwell: float
        dock: tuple[float, float]
        greeting: bool
        shutdown: bool
        _patrol_resume_at: float | None
        _patrol_next: int
        _docked_at: float | None
        power: float
        targets: list[tuple[float, float]]

        @property
        def visual_initialised(self) -> bool: ...
        def _begin_goal(self, target_id: int) -> None: ...

        def set_busy(self, seconds: float) -> None: ...
        def halt(self) -> None: ...
        def _drop_goal(self) -> None: ...
        def _stop_navigation(self, _: object) -> None: ...

    # ------------------------------------------------------------------ patrol
    def _step_power(self, dt: float) -> None:
        config = self.config
        if self.charge_status in (CHARGING, CHARGED):
            self.power = min(config.power_full, self.power + config.charge_rate * dt)
            if self.charge_status == CHARGING and self.power >= config.power_full:
                self.charge_status = CHARGED
        else:
            self.power = max(0.0, self.power - config.power_drain * dt)

    def _step_patrol(self) -> None:
        if not self.loop_status or self.target_status in ACTIVE or not self.visual_initialised:
            return
        if self._patrol_resume_at is None:  # a leg just ended: dwell at the target
            self._patrol_resume_at = self.time + self.patrol_dwell
        if self.time + EPSILON < self._patrol_resume_at or not self.targets:
            return
        target_id = self._patrol_next % len(self.targets)
        self._patrol_next = target_id + 1
        self._patrol_resume_at = None
        self._begin_goal(target_id)

    def _start_patrol(self, _: object) -> None:
        if self.nav_status == 1 and not self.loop_status:
            self.loop_status = 1
            self._patrol_resume_at = self.time  # first leg starts at once

    def _stop_patrol(self, _: object) -> None:
        if not self.config.real_firmware:
            return  # the document stops patrol with 'm' 4 only
        if self.loop_status:
            self.loop_status = 0
            if self.target_status in ACTIVE:
                self._drop_goal()

    def _set_patrol_dwell(self, command: cmd.SetPatrolDwell) -> None:
        self.patrol_dwell = float(command.seconds)
        if self.config.real_firmware:
            self._start_patrol(
                None
            )  # firmware: 'm' 5 TT also starts patrol (docs/protocol.md §2.g)

    # ------------------------------------------------------------------ mapping
    def _start_mapping(self, _: object) -> None:
        if self.map_status == 1:
            return
        self._stop_navigation(None)  # docs/protocol.md §2.h: start mapping also stops navigation
        self.map_status, self.visual_status = 1, 1

    def _stop_mapping(self, _: object) -> None:
        if self.map_status == 1:
            self.map_status, self.visual_status = 0, -1
            self.set_busy(self.config.busy_on_map_stop)

    def _save_map(self, _: object) -> None:
        if not self.config.ignore_save_map:
            self.set_busy(self.config.busy_on_save)

    def _update_map(self, _: object) -> None:
        if self.map_status == 0:
            self._start_mapping(None)

    # ------------------------------------------------------------------ charging & misc
    def _start_charging(self, _: object) -> None:
        if self.charge_status in (CHARGE_FREE, 5):
            if self.target_status in ACTIVE:
                self._drop_goal()
            self.loop_status = 0
            self.charge_status = FINDING

    def _stop_charging(self, _: object) -> None:
        if self.charge_status != CHARGE_FREE:
            self.charge_status, self._docked_at = CHARGE_FREE, None
            self.control_v = self.control_w = 0.0

    def _save_dock(self, _: object) -> None:
        self.dock = (self.x, self.y)

    def _greeting(self, command: cmd.Greeting) -> None:
        self.greeting = command.enabled

    def _shutdown(self, _: object) -> None:
        self.shutdown = True
        self.halt()
