"""What the navigation computer does besides goals, one part of a Robot each: patrol, mapping,
charging. Each validates, then sends through Operations.send."""

from __future__ import annotations

from .._checks import check_int, check_timeout
from ..models import ChargeStatus
from ..protocol import (
    Command,
    SaveDock,
    SaveMap,
    SetPatrolDwell,
    StartCharging,
    StartMapping,
    StartPatrol,
    StopCharging,
    StopMapping,
    StopPatrol,
    UpdateMap,
)
from .operations import NAVIGATING, NOT_NAVIGATING, Confirm, Operations
from .runtime import Deadline

__all__ = ["Charging", "Mapping", "Patrol"]


class Patrol:
    """Auto-patrol over the map's targets (``m`` commands, confirmed by loop_status)."""

    def __init__(self, ops: Operations) -> None:
        self._ops = ops

    async def start(self, dwell: int | None, timeout: float | None) -> None:
        """See Robot.start_patrol."""
        if dwell is not None:
            check_int("dwell", dwell, 0, 255)
        self._ops.check_not_driving("start_patrol")
        command: Command = StartPatrol() if dwell is None else SetPatrolDwell(dwell)
        check_timeout("timeout", timeout)
        await self._ops.send(
            command, what="start_patrol", deadline=Deadline(timeout), require=NAVIGATING,
            then=Confirm(lambda s: s.patrolling, field="loop_status"),
        )  # fmt: skip

    async def stop(self, timeout: float | None) -> None:
        """See Robot.stop_patrol."""
        check_timeout("timeout", timeout)
        # The document's 'm' 4 would stop navigation; firmware stops patrol with 'm' 6
        # (docs/protocol.md §2.g).
        await self._ops.send(
            StopPatrol(), what="stop_patrol", deadline=Deadline(timeout),
            then=Confirm(lambda s: not s.patrolling, field="loop_status"),
        )  # fmt: skip

    async def set_dwell(self, seconds: int, timeout: float | None) -> None:
        """See Robot.set_patrol_dwell."""
        command = SetPatrolDwell(seconds)
        await self._ops.send_unconfirmed(command, "set_patrol_dwell", timeout, require=NAVIGATING)


class Mapping:
    """Building and saving the map, with navigation closed (confirmed by map_status)."""

    def __init__(self, ops: Operations) -> None:
        self._ops = ops

    async def start(self, timeout: float | None) -> None:
        """See Robot.start_mapping."""
        await self._switch(StartMapping(), True, timeout, "start_mapping")

    async def stop(self, timeout: float | None) -> None:
        """See Robot.stop_mapping."""
        await self._switch(StopMapping(), False, timeout, "stop_mapping")

    async def save(self, timeout: float | None) -> None:
        """See Robot.save_map."""
        await self._ops.send_unconfirmed(SaveMap(), "save_map", timeout, require=NOT_NAVIGATING)

    async def update(self, timeout: float | None) -> None:
        """See Robot.update_map."""
        await self._ops.send_unconfirmed(UpdateMap(), "update_map", timeout, require=NOT_NAVIGATING)

    async def _switch(
        self, command: Command, mapping: bool, timeout: float | None, what: str
    ) -> None:
        check_timeout("timeout", timeout)
        await self._ops.send(
            command, what=what, deadline=Deadline(timeout), require=NOT_NAVIGATING,
            then=Confirm(lambda s: s.mapping == mapping, field="map_status"),
        )  # fmt: skip


class Charging:
    """Docking on the charger and the dock position (``j`` commands, confirmed by charge_status)."""

    def __init__(self, ops: Operations) -> None:
        self._ops = ops

    async def start(self, timeout: float | None) -> ChargeStatus:
        """See Robot.start_charging."""
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

    async def stop(self, timeout: float | None) -> None:
        """See Robot.stop_charging."""
        check_timeout("timeout", timeout)
        await self._ops.send(
            StopCharging(), what="stop_charging", deadline=Deadline(timeout),
            then=Confirm(lambda s: s.charge_status == ChargeStatus.FREE, field="charge_status"),
        )  # fmt: skip

    async def save_dock(self, timeout: float | None) -> None:
        """See Robot.save_dock."""
        await self._ops.send_unconfirmed(SaveDock(), "save_dock", timeout)
