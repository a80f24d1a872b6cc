"""Dynamic targets: the driver's count of them on the robot, and the commands that change it."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from ..errors import GoalAborted, InvalidArgument, NotReady
from ..models import GalileoStatus
from ..options import MAX_TARGET_ID
from ..protocol import AddTarget, ResetTargets
from ..transitions import arrived
from .operations import NAVIGATING, Operations, Require, Sent
from .runtime import Deadline

if TYPE_CHECKING:
    from ..state.streams import Watch
    from .goal import GoalResult

__all__ = ["MAX_TARGET_ID", "DynamicTargets", "landed_at"]


class DynamicTargets:
    """The targets a Robot adds after the map's own (no status field shows them)."""

    def __init__(self, ops: Operations, map_targets: int | None) -> None:
        self._ops = ops
        #: How many targets the robot's map has: the first dynamic target's goal id.
        self.map_targets = map_targets
        #: The number of targets the link reported at connect (sim:// the map's; ros://
        #: /galileo/goal_num, dynamic targets included), None when it cannot tell.
        self.link_count: int | None = None
        self._count: int | None = None  # unknown until reset() in this session
        self._reconnects = 0  # link.stats.reconnects when the count was last reset

    def map_target_count(self, what: str) -> int:
        """``map_targets``, checking that the Robot is open; NotReady while it is unknown.

        InvalidArgument when it differs from ``link_count``: the first dynamic target's id
        would be a map target's (or past the last target).
        """
        self._ops.ensure_open()
        count = self.link_count
        if self.map_targets is not None and count is not None and self.map_targets != count:
            raise InvalidArgument(
                f"{what}: map_targets={self.map_targets} contradicts the {count} targets the "
                "link reported at connect, so dynamic target ids would be wrong (a too small "
                "map_targets makes the robot drive to a map target instead); nothing was "
                "sent. Connect without map_targets to use the link's count (ros:// counts "
                "dynamic targets left on the robot too: call reset_targets() and reconnect)"
            )
        if self.map_targets is None:
            raise NotReady(
                f"{what}: the number of targets in the robot's map is unknown (a serial "
                "link cannot read it; ros:// reads /galileo/goal_num, which the robot has "
                "not set); pass map_targets=N to connect() "
                "(galileo CLI: --map-targets N or GALILEO_MAP_TARGETS)",
                self._ops.store.status,
            )
        return self.map_targets

    async def reset(
        self, deadline: Deadline, *, what: str = "reset_targets", require: Require = NAVIGATING,
        stops_at: int | None = None,
    ) -> None:  # fmt: skip
        """Send ``g r 0``: the robot then has no dynamic targets.

        With ``stops_at`` (a goal's step): superseded by a user stop after it (Operations.send).
        """
        await self._ops.send(
            ResetTargets(), what=what, deadline=deadline, require=require, then=_Reset(self),
            supersedable=stops_at is not None, stops_at=stops_at,
        )  # fmt: skip

    async def add(
        self, command: AddTarget, deadline: Deadline, *, stops_at: int | None = None
    ) -> int:
        """Send ``command`` (``g i x y``); the new target's goal id; ``stops_at`` as for reset."""
        adding = _Add(self, self.map_target_count("add_target"))
        try:
            return await self._ops.send(
                command, what="add_target", deadline=deadline, require=NAVIGATING, then=adding,
                supersedable=stops_at is not None, stops_at=stops_at,
            )  # fmt: skip
        except BaseException:
            if adding.target_id is not None:
                self._count = None  # it may or may not have reached the robot
            raise

    def _reserve(self, map_targets: int, status: GalileoStatus | None) -> int:
        """The goal id of the next dynamic target, counted now; NotReady if unknown."""
        if self._count is not None and self._reconnects != self._ops.link.stats.reconnects:
            # A reconnect may mean a restarted robot, which keeps no dynamic targets.
            self._count = None
            raise NotReady(
                "add_target: the link reconnected since reset_targets() (the robot may have "
                "restarted and lost its dynamic targets); call reset_targets() again",
                status,
            )
        if self._count is None:
            raise NotReady(
                "add_target: the number of dynamic targets on the robot is unknown; "
                "call reset_targets() first (goto_point does)",
                status,
            )
        target_id = map_targets + self._count
        if target_id > MAX_TARGET_ID:
            raise NotReady(
                f"add_target: goal ids stop at {MAX_TARGET_ID}; call reset_targets()", status
            )
        self._count += 1  # reserved now: concurrent calls get distinct ids
        return target_id


class _Reset:
    """Follower of ``g r 0``: the count is unknown from the write on, 0 once it is written."""

    __slots__ = ("_targets",)

    def __init__(self, targets: DynamicTargets) -> None:
        self._targets = targets

    def sending(self, before: GalileoStatus | None) -> None:
        """The reset may or may not reach the robot: forget the count until it is written."""
        targets = self._targets
        targets._count = None
        targets._reconnects = targets._ops.link.stats.reconnects

    async def follow(self, watch: Watch, sent: Sent) -> None:
        """Written: the robot now has no dynamic targets."""
        self._targets._count = 0


class _Add:
    """Follower of ``g i x y``: reserves the new target's goal id right before the write."""

    __slots__ = ("_map_targets", "_targets", "target_id")

    def __init__(self, targets: DynamicTargets, map_targets: int) -> None:
        self._targets = targets
        self._map_targets = map_targets
        self.target_id: int | None = None

    def sending(self, before: GalileoStatus | None) -> None:
        """Reserve the goal id (NotReady, nothing sent, when the count is unknown)."""
        self.target_id = self._targets._reserve(self._map_targets, before)

    async def follow(self, watch: Watch, sent: Sent) -> int:
        """Written: the reserved goal id."""
        assert self.target_id is not None
        return self.target_id


def landed_at(result: GoalResult, x: float, y: float, tolerance: float) -> GoalResult:
    """``result`` when its final pose is within ``tolerance`` of (x, y) or unknown; else raise.

    GoalAborted when the robot ended elsewhere: the dynamic target's id was another
    target's (``map_targets`` smaller than the robot's number of targets).
    """
    pose = result.status.pose
    if pose is None:  # v1 layouts and a lost visual system do not show it: nothing to judge
        return result
    distance = math.hypot(pose.x - x, pose.y - y)
    if arrived(distance, tolerance):
        return result
    raise GoalAborted(
        f"goto_point({x:g}, {y:g}): goal {result.target_id} ended at ({pose.x:.2f}, "
        f"{pose.y:.2f}), {distance:.2f} m from the requested point (arrive_tolerance "
        f"{tolerance} m): the target numbering looks wrong: map_targets is probably smaller "
        f"than the number of targets in the robot's map, so goal {result.target_id} was a "
        "map target",
        target_id=result.target_id,
        distance=distance,
        status=result.status,
    )
