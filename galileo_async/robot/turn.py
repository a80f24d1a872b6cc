"""Turning in place by velocity (drive()), closed loop on current_angle: works on every firmware."""

from __future__ import annotations

import math
from typing import Protocol

import anyio

from .._checks import check_number, check_timeout
from ..errors import CommandSuperseded, GalileoError, GalileoTimeout
from ..models import GalileoStatus
from ..state.store import StatusStream
from .drive import DriveSession, SpeedLimits

__all__ = [
    "MAX_TURN_RATE",
    "MIN_TURN_RATE",
    "TURN_GAIN",
    "Turnable",
    "turn_in_place",
]

#: rad/s per radian of heading error (proportional control).
TURN_GAIN = 1.5
#: rad/s: the slowest turn commanded, so that a small error still moves the wheels.
MIN_TURN_RATE = 0.15
#: rad/s: the fastest turn commanded (also bounded by the robot's speed limits).
MAX_TURN_RATE = 1.0


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
