"""Goal progress, as nav2's progress checker: a goal that neither moves nor nears stalls."""

from __future__ import annotations

import math

from ..errors import GoalStalled
from ..models import GalileoStatus, Pose, TargetStatus
from ..options import DEFAULT_PROGRESS_TIMEOUT
from ..transitions import valid_distance

__all__ = ["DEFAULT_PROGRESS_TIMEOUT", "PROGRESS_RADIUS", "ProgressCheck"]

#: Metres the pose must move, or target_distance fall, to count as progress.
PROGRESS_RADIUS = 0.1


class ProgressCheck:
    """Whether a running goal progressed within ``timeout`` s of unpaused time (no I/O).

    Progress: the pose moved PROGRESS_RADIUS from where it was at the last progress, or
    target_distance fell PROGRESS_RADIUS below its value then. Paused time does not count,
    nor time without frames (``discount``).
    """

    def __init__(self, target_id: int, timeout: float, status: GalileoStatus, now: float) -> None:
        self.target_id = target_id
        self.timeout = timeout
        self._since = now  # start of the current unpaused stretch without progress
        self._spent = 0.0  # unpaused seconds without progress before _since
        self._paused = False
        self._pose: Pose | None = None
        self._distance: float | None = None
        self.feed(status, now)

    def feed(self, status: GalileoStatus, now: float) -> None:
        """Account for ``status``, received at loop time ``now``."""
        paused = status.target_status == TargetStatus.PAUSED
        if paused and not self._paused:
            self._spent += now - self._since
        elif self._paused and not paused:
            self._since = now
        self._paused = paused
        pose, distance = status.pose, valid_distance(status.target_distance)
        moved = pose is not None and self._pose is not None and _apart(pose, self._pose)
        nearer = (
            distance is not None
            and self._distance is not None
            and self._distance - distance >= PROGRESS_RADIUS
        )
        if moved or nearer:
            self._spent, self._since = 0.0, now
            self._pose, self._distance = pose, distance
            return
        # A value unknown so far (pose lost, distance -1) becomes the reference once known.
        self._pose = self._pose or pose
        self._distance = distance if self._distance is None else self._distance

    def discount(self, seconds: float) -> None:
        """Leave ``seconds`` just past out of the clock: no frame came then (a stale link)."""
        if not self._paused:
            self._since += seconds

    def deadline(self) -> float | None:
        """Loop time at which the goal stalls without further progress; None while paused."""
        return None if self._paused else self._since + self.timeout - self._spent

    def check(self, status: GalileoStatus | None, now: float) -> None:
        """Raise GoalStalled once the deadline has passed at loop time ``now``."""
        deadline = self.deadline()
        if deadline is None or now < deadline:
            return
        stalled_for = self._spent + now - self._since
        raise GoalStalled(
            f"goal {self.target_id} made no progress for {stalled_for:.1f} s (neither the pose "
            f"moved nor target_distance fell {PROGRESS_RADIUS} m within progress_timeout "
            f"{self.timeout} s): the navigation stack may have died behind a live serial "
            "node, or the robot is blocked",
            target_id=self.target_id,
            stalled_for=stalled_for,
            status=status,
        )


def _apart(a: Pose, b: Pose) -> bool:
    return math.hypot(a.x - b.x, a.y - b.y) >= PROGRESS_RADIUS
