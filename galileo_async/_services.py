"""Robot operations outside goals: teleoperation, patrol, mapping, charging, the host."""

from __future__ import annotations

import asyncio
from collections.abc import Callable

from ._checks import check_int, check_number
from ._goal import GoalHandle
from ._operations import (
    DEFAULT_TIMEOUT,
    ROTATE_TIMEOUT,
    Deadline,
    DynamicTargets,
    Operations,
    check_timeout,
)
from .errors import (
    GalileoConnectionError,
    GalileoTimeout,
    InvalidArgument,
    LinkStale,
    NotReady,
    OperationFailed,
    UnconfirmedOperation,
    WrongEventLoop,
)
from .models import AngleGoalStatus, ChargeStatus, GalileoStatus, TargetStatus
from .protocol import (
    AddTarget,
    Backward,
    Cancel,
    Command,
    Forward,
    Pause,
    ResetTargets,
    Resume,
    RotateTo,
    SaveDock,
    SaveMap,
    SetPatrolDwell,
    ShutdownHost,
    StartCharging,
    StartMapping,
    StartPatrol,
    Stop,
    StopCharging,
    StopMapping,
    StopPatrol,
    TurnLeft,
    TurnRight,
    UpdateMap,
)

__all__ = ["MAX_TARGET_ID", "RobotServices"]

#: Highest goal id the ``g`` command can carry.
MAX_TARGET_ID = 255


def _navigating(status: GalileoStatus) -> bool:
    return status.navigating


class _Rotation:
    """Tells from the statuses after ``a`` whether the rotation rotate_to sent is done."""

    __slots__ = ("_goal_id", "_started", "_what")

    def __init__(self, what: str, before: GalileoStatus) -> None:
        self._what = what
        self._goal_id = before.target_num_id
        self._started = False

    def done(self, status: GalileoStatus) -> bool:
        """True once the rotation is done; OperationFailed once a navigation goal ran."""
        if status.goal_active or status.target_num_id != self._goal_id:
            # A goal replaces a rotation, and real firmware derives angle_goal_status from
            # the goal state (PROTOCOL.md §1 field 12): its 0 then 1 would look like ours.
            raise OperationFailed(
                f"{self._what}: navigation goal {status.target_num_id} started while "
                "waiting for the rotation; a goal replaces a rotation, and angle_goal_status "
                "then follows the goal",
                status,
            )
        # A stale 1 (done) shows before the rotation starts: wait for 0 then 1.
        self._started = self._started or status.angle_goal_status == AngleGoalStatus.NOT_DONE
        return self._started and status.angle_goal_status == AngleGoalStatus.DONE


class RobotServices:
    """Operations every Robot has besides goals; each validates, checks, sends, confirms."""

    _ops: Operations
    _closed: bool
    _loop: asyncio.AbstractEventLoop
    _goal: GoalHandle | None
    _targets: DynamicTargets
    map_targets: int | None

    # --- goal control ---------------------------------------------------------------

    async def pause(self, *, timeout: float | None = DEFAULT_TIMEOUT) -> None:
        """Pause the working goal; return once the status shows it paused."""
        await self._goal_command(Pause(), TargetStatus.WORKING, TargetStatus.PAUSED, timeout)

    async def resume(self, *, timeout: float | None = DEFAULT_TIMEOUT) -> None:
        """Resume the paused goal; return once the status shows it working."""
        await self._goal_command(Resume(), TargetStatus.PAUSED, TargetStatus.WORKING, timeout)

    async def cancel(self, *, timeout: float | None = DEFAULT_TIMEOUT) -> None:
        """Cancel the goal (sent at once, even while busy or stale); return once none is active.

        On a stale link ``i 2`` is still sent (the transmit side may work), then LinkStale
        is raised: the status cannot confirm it.
        """
        check_timeout("timeout", timeout)
        self._ensure_open()
        if self._goal is not None:
            self._goal.cancelled = True  # its end is then reported as cancelled
        await self._ops.link.send(Cancel())
        stale = self._ops.store.link_error
        if isinstance(stale, LinkStale):
            raise LinkStale(
                f"cancel: sent, but the status cannot confirm it: {stale}",
                silent_for=stale.silent_for,
            )
        try:
            await self._ops.store.wait_until(lambda s: not s.goal_active, timeout=timeout)
        except GalileoTimeout as exc:
            raise UnconfirmedOperation(
                f"cancel: sent, but a goal was still active after {timeout} s", exc.status
            ) from None

    async def rotate_to(self, degrees: float, *, timeout: float | None = ROTATE_TIMEOUT) -> None:
        """Rotate to ``degrees`` (-180..180, rounded) in the map frame; wait angle_goal_status.

        Returns once angle_goal_status shows this rotation done (0, then 1). A navigation
        goal that runs meanwhile (this Robot's or another host's) raises OperationFailed:
        it replaces the rotation, and on real firmware angle_goal_status follows it.
        """
        command = RotateTo(round(check_number("degrees", degrees)))
        check_timeout("timeout", timeout)
        what = f"rotate_to({degrees})"
        deadline = Deadline(timeout)
        before = await self._require(
            lambda s: s.visual_initialised and not s.goal_active,
            "rotate_to: the visual system must be initialised and no goal active",
            deadline,
        )
        rotation = _Rotation(what, before)
        try:
            await self._ops.send_confirmed(
                command, rotation.done, field="angle_goal_status", deadline=deadline,
                what=what, failed=lambda s: s.angle_goal_status == AngleGoalStatus.ERROR,
            )  # fmt: skip
        except UnconfirmedOperation as exc:
            # No published firmware handles 'a' (PROTOCOL.md §2.g).
            raise UnconfirmedOperation(
                f"{exc}; many firmware versions ignore the rotate command 'a' entirely",
                exc.status,
            ) from None

    # --- dynamic targets -------------------------------------------------------------

    async def add_target(
        self, x: float, y: float, *, timeout: float | None = DEFAULT_TIMEOUT
    ) -> int:
        """Append a dynamic target at (x, y) metres in the map frame; return its goal id."""
        command = AddTarget(x, y)
        check_timeout("timeout", timeout)
        return await self._add_target(command, Deadline(timeout))

    async def reset_targets(self, *, timeout: float | None = DEFAULT_TIMEOUT) -> None:
        """Drop every dynamic target (the map's own stay); not confirmable by status."""
        check_timeout("timeout", timeout)
        await self._reset_targets(Deadline(timeout))

    # --- teleoperation ---------------------------------------------------------------

    async def forward(self, percent: int, *, timeout: float | None = DEFAULT_TIMEOUT) -> None:
        """Drive forward at ``percent`` (0-100) of max speed until changed; not confirmed."""
        await self._send(Forward(percent), timeout, "forward")

    async def backward(self, percent: int, *, timeout: float | None = DEFAULT_TIMEOUT) -> None:
        """Drive backward at ``percent`` (0-100) of max speed until changed; not confirmed."""
        await self._send(Backward(percent), timeout, "backward")

    async def turn_left(self, percent: int, *, timeout: float | None = DEFAULT_TIMEOUT) -> None:
        """Turn left at ``percent`` (0-100) of max angular speed until changed; not confirmed."""
        await self._send(TurnLeft(percent), timeout, "turn_left")

    async def turn_right(self, percent: int, *, timeout: float | None = DEFAULT_TIMEOUT) -> None:
        """Turn right at ``percent`` (0-100) of max angular speed until changed; not confirmed."""
        await self._send(TurnRight(percent), timeout, "turn_right")

    async def stop(self, brake: int = 100) -> None:
        """Zero both speeds with ``brake`` (0-100); sent at once, even while busy or stale."""
        command = Stop(brake)
        self._ensure_open()
        await self._ops.link.send(command)

    # --- patrol, mapping, charging, host -------------------------------------------------

    async def start_patrol(
        self, dwell: int | None = None, *, timeout: float | None = DEFAULT_TIMEOUT
    ) -> None:
        """Start auto-patrol (``dwell`` s at each target if given); return once loop_status is 1."""
        if dwell is not None:
            check_int("dwell", dwell, 0, 255)
        command: Command = StartPatrol() if dwell is None else SetPatrolDwell(dwell)
        check_timeout("timeout", timeout)
        deadline = Deadline(timeout)
        await self._require(_navigating, "start_patrol: navigation must be open", deadline)
        await self._ops.send_confirmed(
            command, lambda s: s.patrolling, field="loop_status", deadline=deadline,
            what="start_patrol",
        )  # fmt: skip

    async def stop_patrol(self, *, timeout: float | None = DEFAULT_TIMEOUT) -> None:
        """Stop auto-patrol, keep navigation (``m 6``); return once loop_status is 0."""
        check_timeout("timeout", timeout)
        deadline = Deadline(timeout)
        await self._require(lambda s: True, "stop_patrol", deadline)
        # The document's 'm' 4 would stop navigation; firmware stops patrol with 'm' 6
        # (PROTOCOL.md §2.g).
        await self._ops.send_confirmed(
            StopPatrol(), lambda s: not s.patrolling, field="loop_status",
            deadline=deadline, what="stop_patrol",
        )  # fmt: skip

    async def set_patrol_dwell(
        self, seconds: int, *, timeout: float | None = DEFAULT_TIMEOUT
    ) -> None:
        """Set the patrol wait at each target (0-255 s); the firmware also starts patrol."""
        command = SetPatrolDwell(seconds)
        check_timeout("timeout", timeout)
        deadline = Deadline(timeout)
        await self._require(_navigating, "set_patrol_dwell: navigation must be open", deadline)
        await self._send(command, timeout, "set_patrol_dwell", deadline)

    async def start_mapping(self, *, timeout: float | None = DEFAULT_TIMEOUT) -> None:
        """Start building a map; return once map_status is 1. Navigation must be closed."""
        await self._mapping_command(StartMapping(), True, timeout, "start_mapping")

    async def stop_mapping(self, *, timeout: float | None = DEFAULT_TIMEOUT) -> None:
        """Stop building the map; return once map_status is 0."""
        await self._mapping_command(StopMapping(), False, timeout, "stop_mapping")

    async def save_map(self, *, timeout: float | None = DEFAULT_TIMEOUT) -> None:
        """Save the map; the status cannot confirm it and some firmware ignores it."""
        check_timeout("timeout", timeout)
        deadline = Deadline(timeout)
        await self._require(
            lambda s: not s.navigating, "save_map: navigation must be closed", deadline
        )
        await self._send(SaveMap(), timeout, "save_map", deadline)

    async def update_map(self, *, timeout: float | None = DEFAULT_TIMEOUT) -> None:
        """Update the map; the status cannot confirm it."""
        check_timeout("timeout", timeout)
        deadline = Deadline(timeout)
        await self._require(
            lambda s: not s.navigating, "update_map: navigation must be closed", deadline
        )
        await self._send(UpdateMap(), timeout, "update_map", deadline)

    async def start_charging(self, *, timeout: float | None = DEFAULT_TIMEOUT) -> ChargeStatus:
        """Dock and charge (``j 0``); return the charge_status once it leaves FREE.

        This is the local infrared docking only: it does not cross the map. The robot must
        already be near the dock with navigation open; drive it there first (``goto_point``).
        """
        check_timeout("timeout", timeout)
        deadline = Deadline(timeout)
        await self._require(lambda s: True, "start_charging", deadline)
        status = await self._ops.send_confirmed(
            StartCharging(), lambda s: s.charge_status not in (None, ChargeStatus.FREE),
            field="charge_status", deadline=deadline, what="start_charging",
            failed=lambda s: s.charge_status == ChargeStatus.ERROR,
        )  # fmt: skip
        assert status.charge_status is not None
        return status.charge_status

    async def stop_charging(self, *, timeout: float | None = DEFAULT_TIMEOUT) -> None:
        """Stop charging; return once charge_status is FREE."""
        check_timeout("timeout", timeout)
        deadline = Deadline(timeout)
        await self._require(lambda s: True, "stop_charging", deadline)
        await self._ops.send_confirmed(
            StopCharging(), lambda s: s.charge_status == ChargeStatus.FREE,
            field="charge_status", deadline=deadline, what="stop_charging",
        )  # fmt: skip

    async def save_dock(self, *, timeout: float | None = DEFAULT_TIMEOUT) -> None:
        """Save the current pose as the dock position; the status cannot confirm it."""
        await self._send(SaveDock(), timeout, "save_dock")

    async def shutdown_host(self, *, confirm: bool = False) -> None:
        """Power the navigation computer off; refuses unless ``confirm=True``."""
        if confirm is not True:
            raise InvalidArgument(
                "shutdown_host powers the robot's computer off: pass confirm=True"
            )
        self._ensure_open()
        await self._ops.transmit(ShutdownHost(), "shutdown_host")

    # --- helpers -----------------------------------------------------------------------

    async def _add_target(self, command: AddTarget, deadline: Deadline) -> int:
        map_targets = self._require_map_targets("add_target")
        await self._require(_navigating, "add_target: navigation must be open", deadline)
        await self._ops.wait_not_busy(deadline, "add_target")
        self._ops.check_link("add_target")
        target_id = self._targets.reserve(map_targets, self._ops.store.status, MAX_TARGET_ID)
        try:
            await self._ops.link.send(command)
        except BaseException:
            self._targets.forget()  # it may or may not have reached the robot
            raise
        return target_id

    async def _reset_targets(self, deadline: Deadline) -> None:
        await self._require(_navigating, "reset_targets: navigation must be open", deadline)
        await self._ops.wait_not_busy(deadline, "reset_targets")
        self._ops.check_link("reset_targets")
        self._targets.resetting()
        await self._ops.link.send(ResetTargets())
        self._targets.reset_done()

    def _require_map_targets(self, what: str) -> int:
        self._ensure_open()
        if self.map_targets is None:
            raise NotReady(
                f"{what}: the number of targets in the robot's map is unknown (a serial "
                "link cannot read it; ros:// reads /galileo/goal_num, which the robot has "
                "not set); pass map_targets=N to connect() "
                "(galileo CLI: --map-targets N or GALILEO_MAP_TARGETS)",
                self._ops.store.status,
            )
        return self.map_targets

    def _ensure_open(self) -> None:
        self._ensure_loop()
        if self._closed:
            raise GalileoConnectionError("this Robot is closed")

    def _ensure_loop(self) -> None:
        """Raise WrongEventLoop unless called on the loop that connected this Robot."""
        try:
            loop = asyncio.get_running_loop()
        except RuntimeError:
            loop = None
        if loop is not self._loop:
            # Its transport, timers and futures live on that loop: from another one a call
            # would hang until some unrelated timer fired, or corrupt the link's state.
            raise WrongEventLoop(
                "this Robot is bound to the event loop that connected it and was called "
                + ("from another event loop" if loop is not None else "with no event loop")
                + "; use asyncio.run_coroutine_threadsafe() to call it from another thread"
            )

    async def _require(
        self, ok: Callable[[GalileoStatus], bool], message: str, deadline: Deadline
    ) -> GalileoStatus:
        self._ensure_open()
        return await self._ops.ready(ok, message, deadline)

    async def _send(
        self, command: Command, timeout: float | None, what: str, deadline: Deadline | None = None
    ) -> None:
        check_timeout("timeout", timeout)
        self._ensure_open()
        await self._ops.send(command, deadline or Deadline(timeout), what)

    async def _mapping_command(
        self, command: Command, mapping: bool, timeout: float | None, what: str
    ) -> None:
        check_timeout("timeout", timeout)
        deadline = Deadline(timeout)
        await self._require(
            lambda s: not s.navigating, f"{what}: navigation must be closed", deadline
        )
        await self._ops.send_confirmed(
            command, lambda s: s.mapping == mapping, field="map_status",
            deadline=deadline, what=what,
        )  # fmt: skip

    async def _goal_command(
        self, command: Command, needed: TargetStatus, result: TargetStatus, timeout: float | None
    ) -> None:
        what = type(command).__name__.lower()
        check_timeout("timeout", timeout)
        deadline = Deadline(timeout)
        await self._require(
            lambda s: s.target_status == needed,
            f"{what}: the goal must be {needed.name.lower()}",
            deadline,
        )
        await self._ops.send_confirmed(
            command, lambda s: s.target_status == result, field="target_status",
            deadline=deadline, what=what,
        )  # fmt: skip
