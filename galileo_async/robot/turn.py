"""Turning a Robot to a heading: the firmware's rotate command ``a``, confirmed by
angle_goal_status (rotate), or in place by velocity, closed loop on current_angle, which
works on every firmware (turn_in_place)."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Protocol

import anyio

from .._checks import check_number, check_timeout
from ..errors import CommandSuperseded, GalileoError, GalileoTimeout, OperationFailed
from ..models import AngleGoalStatus, GalileoStatus
from ..protocol import RotateTo
from ..state.store import StatusStream
from .drive import DriveSession, SpeedLimits
from .operations import Confirm, Require
from .runtime import Deadline

if TYPE_CHECKING:
    from .operations import Operations

__all__ = [
    "MAX_TURN_RATE",
    "MIN_TURN_RATE",
    "ROTATE_TIMEOUT",
    "TURN_GAIN",
    "Turnable",
    "rotate",
    "turn_in_place",
]

#: Default seconds of Robot.rotate_to and Robot.turn_to for the robot to face the heading.
ROTATE_TIMEOUT = 20.0
#: rad/s per radian of heading error (proportional control).
TURN_GAIN = 1.5
#: rad/s: the slowest turn commanded, so that a small error still moves the wheels.
MIN_TURN_RATE = 0.15
#: rad/s: the fastest turn commanded (also bounded by the robot's speed limits).
MAX_TURN_RATE = 1.0

_ROTATE_READY = Require(
    lambda s: s.visual_initialised and not s.goal_active,
    "the visual system must be initialised and no goal active",
)


async def rotate(ops: Operations, degrees: float, *, limit: float | None, tolerance: float) -> None:
    """Robot.rotate_to without its fallback: ``a``, then angle_goal_status 0 then 1.

    ``limit``: rotate_to's timeout. Facing ``degrees`` already, within ``tolerance``
    degrees, nothing is sent.
    """
    command = RotateTo(round(check_number("degrees", degrees)))
    check_timeout("timeout", limit)
    what = f"rotate_to({degrees})"

    def halted(by: str) -> CommandSuperseded:
        return CommandSuperseded(f"{what}: ended by {by}", superseded_by=by)

    await ops.send(
        command, what=what, deadline=Deadline(limit), require=_ROTATE_READY,
        unless=_facing(degrees, tolerance), then=_Rotation(what), supersedable=True,
        halt=halted,
    )  # fmt: skip


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


class Turnable(Protocol):
    """What turn_in_place uses of a Robot."""

    angle_tolerance: float
    speed_limits: SpeedLimits

    @property
    def status(self) -> GalileoStatus | None:
        """The latest status."""

    def statuses(self) -> StatusStream:
        """The newest statuses as they come."""

    def drive(self, linear: float = 0.0, angular: float = 0.0) -> DriveSession:
        """A velocity-control session."""


def _error(status: GalileoStatus, degrees: float) -> float | None:
    """Degrees from the heading in ``status`` to ``degrees``, wrapped into [-180, 180)."""
    pose = status.pose
    if pose is None:
        return None
    return (degrees - pose.degrees + 180.0) % 360.0 - 180.0


async def turn_in_place(robot: Turnable, degrees: float, *, limit: float | None) -> None:
    """Turn to ``degrees`` (map frame) with drive(); stop within ``robot.angle_tolerance``.

    The speed is updated at the drive session's rate (5 Hz), not on every status. The stop
    is written on every exit (drive()'s guarantee); a user stop ends the turn at once with
    CommandSuperseded naming it. GalileoTimeout after ``limit`` seconds (None: none).
    """
    target = check_number("degrees", degrees)
    check_timeout("timeout", limit)
    tolerance = robot.angle_tolerance
    status = robot.status
    off = None if status is None else _error(status, target)
    if off is not None and abs(off) <= tolerance:
        return
    fastest = min(MAX_TURN_RATE, robot.speed_limits.angular)
    try:
        with anyio.fail_after(limit):
            # A user stop ends the session, and with it this block: CommandSuperseded.
            async with robot.drive(0.0, 0.0) as session:
                async for status in robot.statuses():
                    off = _error(status, target)
                    if off is None:
                        continue  # the heading is unknown in this frame
                    if abs(off) <= tolerance:
                        return
                    rate = min(max(TURN_GAIN * math.radians(abs(off)), MIN_TURN_RATE), fastest)
                    # The first speed at once; later ones ride on the keep-alive, so the turn
                    # writes at the session's rate, not at the status rate (30 Hz).
                    session.set(angular=math.copysign(rate, off), write=not session.angular)
    except CommandSuperseded as exc:
        by = exc.superseded_by
        raise CommandSuperseded(f"turn_to({degrees}): ended by {by}", superseded_by=by) from None
    except TimeoutError as exc:
        if isinstance(exc, GalileoError):
            raise
        raise GalileoTimeout(
            f"turn_in_place({degrees}): not within {tolerance:g}° after {limit} s",
            robot.status,
        ) from None
