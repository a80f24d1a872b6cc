"""The simulated robot: pure state machines and kinematics, stepped by dt (no asyncio)."""

from __future__ import annotations

import math
import random
from collections import deque
from collections.abc import Callable
from typing import Any

from .._checks import check_int, check_names, check_number
from ..models import STATUS_FIELDS, GalileoStatus, StatusLayout
from ..protocol import commands as cmd
from .config import FRAME_RATE, SimConfig
from .motion import Body, turn_toward, wrap_angle
from .states import (
    ACTIVE,
    CHARGE_FREE,
    CHARGED,
    CHARGING,
    DOCKING,
    EPSILON,
    ERROR,
    FINDING,
    FREE,
    INVALID,
    PAUSED,
    WORKING,
)

__all__ = ["FRAME_TIME", "SETTABLE_FIELDS", "WIRE_FIELDS", "RobotModel", "WireValues"]

#: Simulated seconds per status frame.
FRAME_TIME = 1.0 / FRAME_RATE
#: The v2 status fields in struct order without time_stamp: what ``wire_values`` returns.
WIRE_FIELDS: tuple[str, ...] = tuple(f for f in STATUS_FIELDS if f != "time_stamp")
#: Status values in WIRE_FIELDS order.
WireValues = tuple[Any, ...]

_UNKNOWN_POSE = (-1.0, -1.0, -1.0)

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


class RobotModel(Body):
    """One Galileo robot: feed it commands with ``submit`` and advance it with ``step``."""

    def __init__(self, config: SimConfig | None = None) -> None:
        config = config or SimConfig()
        super().__init__(config)
        self.rng = random.Random(config.seed)
        self.time = 0.0
        self.time_stamp = 0
        self.targets: list[tuple[float, float]] = list(config.targets)
        self.dock = config.dock
        self.patrol_dwell = config.patrol_dwell
        self.power = config.power
        self.greeting = True
        self.shutdown = False
        self.commands_handled = 0
        self.commands_dropped = 0
        # Wire state: defaults until navigation starts (docs/protocol.md §1).
        self.nav_status = 0
        self.visual_status = 0
        self.map_status = 0
        self.charge_status = CHARGE_FREE
        self.loop_status = 0
        self.target_num_id = -1
        self.target_status = INVALID
        self.target_distance = -1.0
        self.rotate_status = -1  # document mode's own angle_goal_status
        self.busy_until = 0.0
        self._pending: deque[tuple[float, cmd.Command]] = deque()
        self._last_start: float | None = None
        self._visual_ready_at: float | None = None
        self._goal: tuple[float, float] | None = None
        self._abort_within: float | None = None
        self._abort_next = config.faults.planner_abort == "next"
        self._reject_next = False
        self._visual_lost_until: float | None = None
        self._goal_issued = False
        self._goal_started_at: float | None = None
        # Faults.freeze_after: the status the dead navigation stack left behind.
        self._frozen: WireValues | None = None
        # A goal or rotation accepted since the last frame: it shows as running in at
        # least one frame (the planner needs a cycle), so a host can see it start.
        self._fresh = False
        self._rotate_goal: float | None = None
        self._patrol_next = 0
        self._patrol_resume_at: float | None = None
        self._docked_at: float | None = None
        #: When the last speed command (f, b, c, d) arrived: the chassis watchdog's clock.
        self._speed_at = 0.0
        self._handlers: dict[type[cmd.Command], Callable[[Any], None]] = {
            cmd.StartNavigation: self._start_navigation,
            cmd.StopNavigation: self._stop_navigation,
            cmd.Goto: self._goto,
            cmd.Pause: self._pause,
            cmd.Resume: self._resume,
            cmd.Cancel: self._cancel,
            cmd.AddTarget: self._add_target,
            cmd.ResetTargets: self._reset_targets,
            cmd.Forward: lambda c: self._teleop(v=c.percent / 100 * config.max_speed),
            cmd.Backward: lambda c: self._teleop(v=-c.percent / 100 * config.max_speed),
            cmd.TurnLeft: lambda c: self._teleop(w=c.percent / 100 * config.max_turn_rate),
            cmd.TurnRight: lambda c: self._teleop(w=-c.percent / 100 * config.max_turn_rate),
            cmd.Stop: lambda c: self._teleop(v=0.0, w=0.0),
            cmd.ShutdownHost: self._shutdown,
            cmd.RotateTo: self._rotate,
            cmd.StartPatrol: self._start_patrol,
            cmd.StopPatrol: self._stop_patrol,
            cmd.SetPatrolDwell: self._set_patrol_dwell,
            cmd.StartMapping: self._start_mapping,
            cmd.StopMapping: self._stop_mapping,
            cmd.SaveMap: self._save_map,
            cmd.UpdateMap: self._update_map,
            cmd.StartCharging: self._start_charging,
            cmd.StopCharging: self._stop_charging,
            cmd.SaveDock: self._save_dock,
            cmd.Greeting: self._greeting,
        }

    # ------------------------------------------------------------------ queries
    @property
    def busy(self) -> bool:
        """busy_status: commands wait until it ends."""
        return self.time + EPSILON < self.busy_until

    @property
    def pending(self) -> int:
        """Commands waiting for busy to end."""
        return len(self._pending)

    @property
    def visual_initialised(self) -> bool:
        """Visual SLAM tracking (or lost): goals and a known pose need it."""
        return self.visual_status in (1, 2)

    @property
    def angle_goal_status(self) -> int:
        """Real firmware derives it from the goal state (docs/protocol.md §1 field 12, §2.g)."""
        if not self.config.real_firmware:
            return self.rotate_status
        if self.target_status == FREE:
            return 1
        return 0 if self.target_status in ACTIVE else -1

    def wire_values(self) -> WireValues:
        """The status as sent now: the 20 v2 fields in struct order, time_stamp left out."""
        if self._frozen is not None:
            return self._frozen
        pose = (self.x, self.y, self.theta) if self.visual_initialised else _UNKNOWN_POSE
        return (
            self.nav_status, self.visual_status, self.map_status, 0, 0, self.charge_status,
            self.loop_status, round(self.power, 2), self.target_num_id, self.target_status,
            self.target_distance, self.angle_goal_status, self.control_v, self.control_w,
            self.current_v, self.current_w, *pose, int(self.busy),
        )  # fmt: skip

    def status(self) -> GalileoStatus:
        """The current status (with time_stamp) as a full v2 GalileoStatus."""
        values = dict(zip(WIRE_FIELDS, self.wire_values(), strict=True))
        values["time_stamp"] = self.time_stamp
        return GalileoStatus.model_validate({**values, "layout": StatusLayout.V2})

    # ------------------------------------------------------------------ input
    def submit(self, command: cmd.Command) -> None:
        """Hand a parsed command to the robot: handled now, or queued while busy."""
        if self.shutdown or self._frozen is not None:
            return
        if self.busy or self._pending:
            self._pending.append((self.time, command))
            return
        self._handle(command)

    def _handle(self, command: cmd.Command) -> None:
        handler = self._handlers.get(type(command))
        self.commands_handled += 1
        if handler is not None:  # unknown payloads (RawCommand) are ignored, like the firmware
            handler(command)

    # ------------------------------------------------------------------ time
    def tick(self) -> None:
        """Advance one status frame: 1/30 s, and time_stamp + 1 (nothing after shutdown)."""
        if not self.shutdown:
            self.step(FRAME_TIME)
            self.time_stamp += 1

    def step(self, dt: float) -> None:
        """Advance simulated time by ``dt`` seconds (one frame is 1/30 s)."""
        if self.shutdown:
            return
        self.time += dt
        if self._frozen is not None:
            return  # the navigation stack is dead: nothing moves or changes
        if self._visual_ready_at is not None and self.time + EPSILON >= self._visual_ready_at:
            self._visual_ready_at = None
            self.visual_status = 1
        self.step_script()
        if self._pending and not self.busy:
            self._drain_pending()
        self._step_patrol()
        self._step_motion(dt)
        self._step_power(dt)
        if self._goal_fault_due(self.config.faults.freeze_after):
            self._frozen = self.wire_values()

    def _drain_pending(self) -> None:
        while self._pending and not self.busy and not self.shutdown:
            queued_at, command = self._pending.popleft()
            if self.time - queued_at > self.config.busy_max_wait:
                self.commands_dropped += 1
                continue
            self._handle(command)

    def _step_motion(self, dt: float) -> None:
        config = self.config
        if self.target_status == WORKING and self._goal is not None:
            self._drive_goal(dt)
        elif self._rotate_goal is not None:
            self.control_v = 0.0
            self.control_w, done = turn_toward(
                self.theta, self._rotate_goal, config.max_turn_rate, dt
            )
            fresh, self._fresh = self._fresh, False
            if done and not fresh:
                self.theta, self.control_w, self.current_w = self._rotate_goal, 0.0, 0.0
                self._rotate_goal, self.rotate_status = None, 1
        elif self.charge_status == FINDING:
            if self.drive_to(self.dock, dt):
                self.charge_status, self._docked_at = DOCKING, self.time
        elif (
            self.charge_status == DOCKING
            and self._docked_at is not None
            and self.time + EPSILON - self._docked_at >= config.docking_time
        ):
            self.charge_status = CHARGING
        else:
            self._chassis_watchdog()
        self.integrate(dt)

    def _goal_fault_due(self, after: float | None) -> bool:
        """A fault set to strike ``after`` s into the running goal is due."""
        started = self._goal_started_at
        if after is None or started is None or self.target_status not in ACTIVE:
            return False
        return self.time + EPSILON >= started + after

    def _chassis_watchdog(self) -> None:
        timeout = self.config.cmd_vel_timeout
        if timeout is not None and self.time + EPSILON - self._speed_at >= timeout:
            self.control_v = self.control_w = 0.0

    def _drive_goal(self, dt: float) -> None:
        assert self._goal is not None
        fresh, self._fresh = self._fresh, False
        if self._goal_fault_due(self.config.faults.block_after) or self.visual_status == 2:
            self.halt()  # blocked or lost: the goal stays working
            return
        if self.drive_to(self._goal, dt, land=self._abort_within is None):
            if fresh:  # even a goal the robot stands on shows as working once
                self.target_distance = 0.0
            else:
                self._end_goal(0.0)
            return
        self.target_distance = self.distance_to(self._goal)
        if self._abort_within is not None and self.target_distance <= self._abort_within:
            self._end_goal(self.target_distance)  # the planner gave up (Faults.planner_abort)

    def _end_goal(self, distance: float) -> None:
        self.target_status, self.target_distance = FREE, distance
        self._goal = self._abort_within = None
        self._patrol_resume_at = self.time + self.patrol_dwell  # used only while patrolling
        self.halt()

    # ------------------------------------------------------------------ navigation
    def _start_navigation(self, _: object) -> None:
        window = self.config.effective_start_ignore_time
        if self._last_start is not None and self.time - self._last_start < window:
            return  # firmware ignores a start within 5-30 s of the previous (docs/protocol.md §2.a)
        if self.nav_status == 1 or self.map_status == 1:
            return
        self._last_start = self.time
        self.nav_status, self.visual_status = 1, 0
        self._visual_ready_at = self.time + self.config.visual_init_time
        self.set_busy(self.config.busy_on_start)

    def _stop_navigation(self, _: object) -> None:
        # 'm' 4 stops navigation, patrol and the goal, and zeroes the speed (docs/protocol.md §2.a).
        if self.target_status in ACTIVE:
            self._drop_goal()
        self.nav_status, self.loop_status = 0, 0
        if self.map_status == 0:
            self.visual_status = -1
        self._visual_ready_at = None
        self._rotate_goal = None
        self.halt()

    def _drop_goal(self) -> None:
        self.target_status = FREE
        if self.config.real_firmware:
            self.target_num_id = -1
        self._goal = self._abort_within = None
        self.halt()

    def _goto(self, command: cmd.Goto) -> None:
        if self.nav_status != 1 or not self.visual_initialised:
            return  # docs/protocol.md §2.b: ignored until the visual system is initialised
        self.loop_status = 0  # a goal by hand ends the patrol
        self._begin_goal(command.target_id)

    def _begin_goal(self, target_id: int) -> None:
        self._goal_issued = True
        self._rotate_goal = None
        if self.target_status in ACTIVE:
            self._drop_goal()
        if self.take_rejection() or target_id >= len(self.targets):
            # Firmware reports the error as -1 and keeps the id (docs/protocol.md §2.b).
            if self.config.real_firmware:
                self.target_status = INVALID
            else:
                self.target_status, self.target_num_id = ERROR, target_id
            self.target_distance = -1.0
            return
        if self.charge_status != CHARGE_FREE:
            self.charge_status = CHARGE_FREE
        goal = self.targets[target_id]
        self.target_num_id, self.target_status, self._goal = target_id, WORKING, goal
        self._goal_started_at = self.time
        self.target_distance = self.distance_to(goal)
        self._abort_within = None
        self._fresh = True
        abort = self.config.faults.planner_abort
        if self._abort_next or (abort != "next" and abort > 0 and self.rng.random() < abort):
            self._abort_next = False
            if self.target_distance > 0.02:
                self._abort_within = self.target_distance / 2

    def _pause(self, _: object) -> None:
        if self.target_status == WORKING:
            self.target_status = PAUSED
            self.halt()

    def _resume(self, _: object) -> None:
        if self.target_status == PAUSED:
            self.target_status = WORKING

    def _cancel(self, _: object) -> None:
        self._rotate_goal = None  # the document's angle goal ends with the goal
        if self.target_status in (WORKING, PAUSED, ERROR) or (
            self.target_status == INVALID and (self._goal_issued or self.nav_status == 1)
        ):
            # With navigation open the firmware's status shows an idle goal as free (0):
            # its -1 default is gone after a cancel too (system_monitor's status service).
            self._drop_goal()

    def _add_target(self, command: cmd.AddTarget) -> None:
        if len(self.targets) < 256:
            self.targets.append((command.x, command.y))

    def _reset_targets(self, _: object) -> None:
        del self.targets[len(self.config.targets) :]

    def _teleop(self, *, v: float | None = None, w: float | None = None) -> None:
        # Linear and angular are kept separately (arcs); without cmd_vel_timeout the speed
        # holds until changed, as on chassis builds without a watchdog (docs/protocol.md §6.5).
        self._speed_at = self.time
        if v is not None:
            self.control_v = v
        if w is not None:
            self.control_w = w

    def _rotate(self, command: cmd.RotateTo) -> None:
        if self.config.real_firmware:
            return  # no published firmware handles 'a' (docs/protocol.md §2.g)
        if not self.visual_initialised:
            return
        if self.target_status in ACTIVE:
            self.rotate_status = 2
            return
        self._rotate_goal = wrap_angle(math.radians(command.degrees))
        self.rotate_status = 0
        self._fresh = True

    # ------------------------------------------------------------------ patrol
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
    def _step_power(self, dt: float) -> None:
        config = self.config
        if self.charge_status in (CHARGING, CHARGED):
            self.power = min(config.power_full, self.power + config.charge_rate * dt)
            if self.charge_status == CHARGING and self.power >= config.power_full:
                self.charge_status = CHARGED
        else:
            self.power = max(0.0, self.power - config.power_drain * dt)

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

    # ------------------------------------------------------------------ HTTP API
    def goto_pose(self, x: float, y: float) -> None:
        """A goal by pose, as an HTTP API nav task: target_num_id -2 (docs/protocol.md §5.4)."""
        if self.nav_status == 1 and self.visual_initialised:
            self.targets.append((x, y))  # _begin_goal takes its goal by index
            self._begin_goal(len(self.targets) - 1)
            self.targets.pop()
            self.target_num_id = -2

    def set_speed(self, linear: float, angular: float) -> None:
        """Teleop in m/s and rad/s (the HTTP API's PUT /system/speed)."""
        self._teleop(v=linear, w=angular)

    # ------------------------------------------------------------------ faults and overrides
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

    def go_charge(self) -> None:
        """The robot heads for its dock by itself (a low battery): its goal and patrol end."""
        if self.target_status in ACTIVE:
            self._drop_goal()
        self.loop_status = 0
        self._start_charging(None)

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
