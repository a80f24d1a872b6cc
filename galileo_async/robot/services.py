"""Robot operations besides goto and navigation: goal control, rotation, dynamic targets,
teleoperation, patrol, mapping, charging, the host. Each validates, then Operations.send."""

from __future__ import annotations

from collections.abc import Callable

from .._checks import check_int, check_number, check_timeout
from ..errors import (
    CommandSuperseded,
    GalileoTimeout,
    InvalidArgument,
    LinkStale,
    NotReady,
    OperationFailed,
    UnconfirmedOperation,
)
from ..models import AngleGoalStatus, ChargeStatus, GalileoStatus, TargetStatus
from ..options import DEFAULT_ANGLE_TOLERANCE
from ..protocol import (
    AddTarget,
    Backward,
    Cancel,
    Command,
    Forward,
    Goto,
    Pause,
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
from .drive import DriveSlot
from .goal import GoalRunner
from .operations import (
    DEFAULT_TIMEOUT,
    NAVIGATING,
    NOT_NAVIGATING,
    ROTATE_TIMEOUT,
    Confirm,
    Operations,
    Require,
)
from .runtime import Deadline
from .stopping import DEFAULT_STOP_TIMEOUT, StopReport, stop_motion
from .targets import DynamicTargets

__all__ = ["DEFAULT_ANGLE_TOLERANCE", "RobotServices"]


_ROTATE_READY = Require(
    lambda s: s.visual_initialised and not s.goal_active,
    "the visual system must be initialised and no goal active",
)


#: What a user stop supersedes while it waits (Operations.user_stopped): drive commands, and
#: a goal sent as is with send().
_SUPERSEDABLE = (Forward, Backward, TurnLeft, TurnRight, Goto)


class _Rotation(Confirm):
    """Confirms ``a``: angle_goal_status 0 then 1, with no navigation goal meanwhile."""

    __slots__ = ("_goal_id", "_started", "_what")

    def __init__(self, what: str) -> None:
        super().__init__(
            self._done, field="angle_goal_status",
            failed=lambda s: s.angle_goal_status == AngleGoalStatus.ERROR,
            # No published firmware handles 'a' (docs/protocol.md §2.g).
            hint="; many firmware versions ignore the rotate command 'a' entirely",
        )  # fmt: skip
        self._what = what
        self._goal_id: int | None = None
        self._started = False

    def sending(self, before: GalileoStatus | None) -> None:
        """Remember the goal id the status shows as ``a`` is written."""
        self._goal_id = None if before is None else before.target_num_id

    def _done(self, status: GalileoStatus) -> bool:
        """True once the rotation is done; OperationFailed once a navigation goal ran."""
        if status.goal_active or status.target_num_id != self._goal_id:
            # A goal replaces a rotation, and real firmware derives angle_goal_status from
            # the goal state (docs/protocol.md §1 field 12): its 0 then 1 would look like ours.
            raise OperationFailed(
                f"{self._what}: navigation goal {status.target_num_id} started while "
                "waiting for the rotation; a goal replaces a rotation, and angle_goal_status "
                "then follows the goal",
                status,
            )
        # A stale 1 (done) shows before the rotation starts: wait for 0 then 1.
        self._started = self._started or status.angle_goal_status == AngleGoalStatus.NOT_DONE
        return self._started and status.angle_goal_status == AngleGoalStatus.DONE


def _facing(degrees: float, tolerance: float) -> Callable[[GalileoStatus], bool]:
    """A predicate: the status shows a heading within ``tolerance`` degrees of ``degrees``."""

    def facing(status: GalileoStatus) -> bool:
        pose = status.pose
        if pose is None:
            return False  # the layout has no heading, or it is unknown: rotate
        off = (pose.degrees - degrees + 180.0) % 360.0 - 180.0  # wrapped into [-180, 180)
        return abs(off) <= tolerance

    return facing


class RobotServices:
    """The Robot's methods besides goto and navigation, on the parts a Robot is made of."""

    def __init__(self, ops: Operations, goals: GoalRunner, targets: DynamicTargets) -> None:
        self._ops = ops
        self._goals = goals
        self._targets = targets
        #: rotate_to within this many degrees of the heading the robot has: done, not sent.
        self.angle_tolerance = DEFAULT_ANGLE_TOLERANCE
        #: The drive session inside whose block the caller is, if any.
        self._drives = DriveSlot()

    # --- goal control ---------------------------------------------------------------

    async def pause(self, *, timeout: float | None = DEFAULT_TIMEOUT) -> None:
        """Pause the working goal; return once the status shows it paused (a user stop)."""
        self._user_stop("pause()")
        await self._goal_command(Pause(), TargetStatus.WORKING, TargetStatus.PAUSED, timeout)

    async def resume(self, *, timeout: float | None = DEFAULT_TIMEOUT) -> None:
        """Resume the paused goal; return once the status shows it working."""
        await self._goal_command(Resume(), TargetStatus.PAUSED, TargetStatus.WORKING, timeout)

    async def cancel(self, *, timeout: float | None = DEFAULT_TIMEOUT) -> None:
        """Cancel the goal (sent at once, even while busy or stale); return once none is active.

        On a stale link ``i 2`` is still sent (the transmit side may work), then LinkStale
        is raised: the status cannot confirm it.
        """
        self._user_stop("cancel()")
        check_timeout("timeout", timeout)
        self._ops.ensure_open()
        self._goals.cancelling()
        await self._ops.send(Cancel(), what="cancel", even_stale=True)
        stale = self._ops.store.link_error
        if isinstance(stale, LinkStale):
            raise LinkStale(
                f"cancel: sent, but the status cannot confirm it: {stale}",
                silent_for=stale.silent_for,
            )
        try:
            await self._ops.store.wait_until(lambda s: not s.goal_active, timeout=timeout)
        except GalileoTimeout as exc:
            if exc.status is None:  # placeholders only: nothing is known of a goal
                raise UnconfirmedOperation(
                    f"cancel: sent, but the navigation system has not reported within "
                    f"{timeout} s (only placeholder frames came), so no status can show it",
                    None,
                ) from None
            raise UnconfirmedOperation(
                f"cancel: sent, but a goal was still active after {timeout} s", exc.status
            ) from None

    async def rotate_to(self, degrees: float, *, timeout: float | None = ROTATE_TIMEOUT) -> None:
        """Rotate to ``degrees`` (-180..180, rounded) in the map frame; wait angle_goal_status.

        Returns once angle_goal_status shows this rotation done (0, then 1). A navigation
        goal that runs meanwhile (this Robot's or another host's) raises OperationFailed:
        it replaces the rotation, and on real firmware angle_goal_status follows it. Facing
        ``degrees`` already, within ``angle_tolerance`` (-180 and 180 are one heading), it
        returns at once and sends nothing.
        """
        command = RotateTo(round(check_number("degrees", degrees)))
        check_timeout("timeout", timeout)
        what = f"rotate_to({degrees})"

        def halted(by: str) -> CommandSuperseded:
            return CommandSuperseded(f"{what}: ended by {by}", superseded_by=by)

        await self._ops.send(
            command, what=what, deadline=Deadline(timeout), require=_ROTATE_READY,
            unless=_facing(degrees, self.angle_tolerance), then=_Rotation(what),
            supersedable=True, halt=halted,
        )  # fmt: skip

    # --- dynamic targets -------------------------------------------------------------

    async def add_target(
        self, x: float, y: float, *, timeout: float | None = DEFAULT_TIMEOUT
    ) -> int:
        """Append a dynamic target at (x, y) metres in the map frame; return its goal id."""
        command = AddTarget(x, y)
        check_timeout("timeout", timeout)
        return await self._targets.add(command, Deadline(timeout))

    async def reset_targets(self, *, timeout: float | None = DEFAULT_TIMEOUT) -> None:
        """Drop every dynamic target (the map's own stay); not confirmable by status."""
        check_timeout("timeout", timeout)
        await self._targets.reset(Deadline(timeout))

    # --- teleoperation ---------------------------------------------------------------

    # One command each: 22 chassis builds hold it until the next, others stop 1-3 s after
    # it (docs/protocol.md §6.5); drive() keeps a speed alive and always ends with a stop.

    async def forward(self, percent: int, *, timeout: float | None = DEFAULT_TIMEOUT) -> None:
        """Write ``f`` once at ``percent`` (0-100) of max speed; the chassis decides how long."""
        await self._written(Forward(percent), "forward", timeout)

    async def backward(self, percent: int, *, timeout: float | None = DEFAULT_TIMEOUT) -> None:
        """Write ``b`` once at ``percent`` (0-100) of max speed; as forward()."""
        await self._written(Backward(percent), "backward", timeout)

    async def turn_left(self, percent: int, *, timeout: float | None = DEFAULT_TIMEOUT) -> None:
        """Write ``c`` once at ``percent`` (0-100) of max angular speed; as forward()."""
        await self._written(TurnLeft(percent), "turn_left", timeout)

    async def turn_right(self, percent: int, *, timeout: float | None = DEFAULT_TIMEOUT) -> None:
        """Write ``d`` once at ``percent`` (0-100) of max angular speed; as forward()."""
        await self._written(TurnRight(percent), "turn_right", timeout)

    async def zero_speed(self, brake: int = 100) -> None:
        """Write one ``Stop(brake)`` (both speeds 0); a goal or patrol drives on. Use stop().

        Sent at once, even while busy or stale; a user stop: a drive or goal command called
        before it that still waits is never written (Operations.user_stopped).
        """
        command = Stop(brake)
        self._user_stop("zero_speed()")
        await self._ops.send(command, what="zero_speed", even_stale=True)

    async def stop(
        self, brake: int = 100, *, timeout: float | None = DEFAULT_STOP_TIMEOUT
    ) -> StopReport:
        """Halt every motion, whoever started it; return once the status shows it stopped.

        Ends this Robot's drive()/turn_to() sessions and every call of it awaiting motion
        at once (goto, goto_point, goto_pose: GoalCancelled; rotate_to, turn_to: CommandSuperseded;
        each naming "stop()"), then writes, even while busy or stale: ``m 6`` (stop patrol)
        unless the status shows none, ``i 2`` (cancel the goal; on http:// the nav task), and
        a stop of both speeds with ``brake`` (0-100). Returns a StopReport once a status shows
        no goal working or paused, no patrol and no speed (a layout without speeds, UDP,
        cannot show one); StopUnconfirmed naming each part still shown after ``timeout`` s,
        or at once on a stale link. ConnectionLost: the link is lost and nothing was sent.
        """
        command = Stop(brake)
        check_timeout("timeout", timeout)
        self._ops.ensure_open()
        drive, goal = self._drives.active, self._goals.running
        self._user_stop("stop()")
        self._goals.cancelling()  # the running goal's end is a cancel, not a planner abort
        tasks = self._ops.halt_motions("stop()")
        return await stop_motion(self._ops, command, timeout, goal=goal, drive=drive, tasks=tasks)

    # --- patrol, mapping, charging, host -------------------------------------------------

    async def start_patrol(
        self, dwell: int | None = None, *, timeout: float | None = DEFAULT_TIMEOUT
    ) -> None:
        """Start auto-patrol (``dwell`` s at each target if given); return once loop_status is 1."""
        if dwell is not None:
            check_int("dwell", dwell, 0, 255)
        self._refuse_while_driving("start_patrol")
        command: Command = StartPatrol() if dwell is None else SetPatrolDwell(dwell)
        check_timeout("timeout", timeout)
        await self._ops.send(
            command, what="start_patrol", deadline=Deadline(timeout), require=NAVIGATING,
            then=Confirm(lambda s: s.patrolling, field="loop_status"),
        )  # fmt: skip

    async def stop_patrol(self, *, timeout: float | None = DEFAULT_TIMEOUT) -> None:
        """Stop auto-patrol, keep navigation (``m 6``); return once loop_status is 0."""
        check_timeout("timeout", timeout)
        # The document's 'm' 4 would stop navigation; firmware stops patrol with 'm' 6
        # (docs/protocol.md §2.g).
        await self._ops.send(
            StopPatrol(), what="stop_patrol", deadline=Deadline(timeout),
            then=Confirm(lambda s: not s.patrolling, field="loop_status"),
        )  # fmt: skip

    async def set_patrol_dwell(
        self, seconds: int, *, timeout: float | None = DEFAULT_TIMEOUT
    ) -> None:
        """Set the patrol wait at each target (0-255 s); the firmware also starts patrol."""
        command = SetPatrolDwell(seconds)
        await self._written(command, "set_patrol_dwell", timeout, require=NAVIGATING)

    async def start_mapping(self, *, timeout: float | None = DEFAULT_TIMEOUT) -> None:
        """Start building a map; return once map_status is 1. Navigation must be closed."""
        await self._mapping_command(StartMapping(), True, timeout, "start_mapping")

    async def stop_mapping(self, *, timeout: float | None = DEFAULT_TIMEOUT) -> None:
        """Stop building the map; return once map_status is 0."""
        await self._mapping_command(StopMapping(), False, timeout, "stop_mapping")

    async def save_map(self, *, timeout: float | None = DEFAULT_TIMEOUT) -> None:
        """Save the map; the status cannot confirm it and some firmware ignores it."""
        await self._written(SaveMap(), "save_map", timeout, require=NOT_NAVIGATING)

    async def update_map(self, *, timeout: float | None = DEFAULT_TIMEOUT) -> None:
        """Update the map; the status cannot confirm it."""
        await self._written(UpdateMap(), "update_map", timeout, require=NOT_NAVIGATING)

    async def start_charging(self, *, timeout: float | None = DEFAULT_TIMEOUT) -> ChargeStatus:
        """Dock and charge (``j 0``); return the charge_status once it leaves FREE.

        This is the local infrared docking only: it does not cross the map. The robot must
        already be near the dock with navigation open; drive it there first (``goto_point``).
        """
        check_timeout("timeout", timeout)
        status = await self._ops.send(
            StartCharging(), what="start_charging", deadline=Deadline(timeout),
            then=Confirm(
                lambda s: s.charge_status not in (None, ChargeStatus.FREE), field="charge_status",
                failed=lambda s: s.charge_status == ChargeStatus.ERROR,
            ),
        )  # fmt: skip
        assert status.charge_status is not None
        return status.charge_status

    async def stop_charging(self, *, timeout: float | None = DEFAULT_TIMEOUT) -> None:
        """Stop charging; return once charge_status is FREE."""
        check_timeout("timeout", timeout)
        await self._ops.send(
            StopCharging(), what="stop_charging", deadline=Deadline(timeout),
            then=Confirm(lambda s: s.charge_status == ChargeStatus.FREE, field="charge_status"),
        )  # fmt: skip

    async def save_dock(self, *, timeout: float | None = DEFAULT_TIMEOUT) -> None:
        """Save the current pose as the dock position; the status cannot confirm it."""
        await self._written(SaveDock(), "save_dock", timeout)

    async def shutdown_host(self, *, confirm: bool = False) -> None:
        """Power the navigation computer off; refuses unless ``confirm=True``."""
        if confirm is not True:
            raise InvalidArgument(
                "shutdown_host powers the robot's computer off: pass confirm=True"
            )
        await self._ops.send(ShutdownHost(), what="shutdown_host")

    # --- helpers -----------------------------------------------------------------------

    def _user_stop(self, what: str) -> None:
        """A user stop: withdraw waiting drive/goal commands, end the drive session (its stop)."""
        self._ops.user_stopped(what)
        self._drives.end(what)

    def _refuse_while_driving(self, what: str) -> None:
        """NotReady inside an active drive block: a goal and the drive's speeds would fight."""
        if self._drives.active:
            raise NotReady(
                f"{what}: a drive session is active; leave its block first", self._ops.store.status
            )

    async def _written(
        self, command: Command, what: str, timeout: float | None, require: Require | None = None
    ) -> None:
        """Send ``command`` (busy back-off within ``timeout``); nothing confirms it."""
        check_timeout("timeout", timeout)
        await self._ops.send(
            command, what=what, deadline=Deadline(timeout), require=require,
            supersedable=isinstance(command, _SUPERSEDABLE),
        )  # fmt: skip

    async def _mapping_command(
        self, command: Command, mapping: bool, timeout: float | None, what: str
    ) -> None:
        check_timeout("timeout", timeout)
        await self._ops.send(
            command, what=what, deadline=Deadline(timeout), require=NOT_NAVIGATING,
            then=Confirm(lambda s: s.mapping == mapping, field="map_status"),
        )  # fmt: skip

    async def _goal_command(
        self, command: Command, needed: TargetStatus, result: TargetStatus, timeout: float | None
    ) -> None:
        what = type(command).__name__.lower()
        check_timeout("timeout", timeout)
        await self._ops.send(
            command, what=what, deadline=Deadline(timeout),
            require=Require(
                lambda s: s.target_status == needed, f"the goal must be {needed.name.lower()}"
            ),
            then=Confirm(lambda s: s.target_status == result, field="target_status"),
        )  # fmt: skip
