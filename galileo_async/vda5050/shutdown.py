"""A vehicle's clean stop: its order cancelled as cancelOrder does, the robot stopped, said so.

VDA 5050 §6.6.3 (order cancellation): the vehicle stops, actions scheduled or running are
cancelled and report FAILED, the order is deleted with its orderId and orderUpdateId kept.
A vehicle that shuts down does that to whatever runs, then tells its master control in a
last state before OFFLINE.
"""

from __future__ import annotations

import contextlib
import logging
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol

import anyio

from ..errors import GalileoError
from ..models import ChargeStatus
from . import report
from .models import Error, reference
from .session import OFFLINE_TIMEOUT

if TYPE_CHECKING:
    from .. import StopReport
    from ..robot import Robot
    from .actions import ActionRunner
    from .config import VehicleConfig
    from .execution import Executor
    from .order import OrderProgress

__all__ = [
    "SHUTDOWN_STEP_TIMEOUT",
    "SHUTDOWN_TIMEOUT",
    "Shutdown",
    "ShutdownHost",
    "ShutdownReport",
]

_log = logging.getLogger(__name__)

#: Seconds a shutdown may spend stopping the robot (then it says what was left undone).
SHUTDOWN_TIMEOUT = 15.0
#: Seconds each of its steps may take: the cancel, the end of docking, the stop, standing still.
SHUTDOWN_STEP_TIMEOUT = 5.0
#: The charge states of a robot on its way to the dock (a running startCharging).
_DOCKING = (ChargeStatus.FINDING_DOCK, ChargeStatus.DOCKING)


@dataclass(frozen=True)
class ShutdownReport:
    """What Vehicle.shut_down() did; ``str()`` says it in one line."""

    #: Why the vehicle shut down (in the FAILED actions and the vehicleShutdown error).
    reason: str
    #: The order that was cancelled; None when none was running.
    order_id: str | None = None
    #: The actionIds of the actions that became FAILED.
    failed_actions: tuple[str, ...] = ()
    #: What Robot.stop() reported; None when it did not (see ``problems``).
    stop: StopReport | None = None
    #: What could not be done, in words ("stop: ConnectionLost: …").
    problems: tuple[str, ...] = ()

    def __str__(self) -> str:
        parts = [f"order {self.order_id} cancelled" if self.order_id else "no order was running"]
        if self.stop is not None:
            parts.append(f"robot stopped ({self.stop})" if self.stop.stopped else "robot stopped")
        if self.failed_actions:
            parts.append("actions FAILED: " + ", ".join(self.failed_actions))
        return ", ".join([*parts, *self.problems])


class ShutdownHost(Protocol):
    """What a shutdown uses of its vehicle (vehicle.Vehicle is one)."""

    @property
    def robot(self) -> Robot:
        """The robot the vehicle drives."""

    @property
    def config(self) -> VehicleConfig:
        """The vehicle's configuration."""

    @property
    def progress(self) -> OrderProgress:
        """The vehicle's order progress."""

    @property
    def executor(self) -> Executor:
        """The vehicle's order executor."""

    @property
    def actions(self) -> ActionRunner:
        """The vehicle's instant actions."""

    def changed(self) -> None:
        """The state changed: publish it soon."""

    async def publish_state(self) -> None:
        """Publish the state now."""


class Shutdown:
    """One vehicle's shutdown: done once (shielded, bounded); its report and its error."""

    def __init__(self, vehicle: ShutdownHost) -> None:
        self._vehicle = vehicle
        self._lock = anyio.Lock()
        #: The report of the shutdown; None before it ran.
        self.report: ShutdownReport | None = None
        #: The vehicleShutdown error of state.errors (empty when nothing was cut short).
        self.errors: list[Error] = []
        #: True from the start of the shutdown: orders and instant actions are refused.
        self.started = False

    async def __call__(self, reason: str) -> ShutdownReport:
        with anyio.CancelScope(shield=True):
            async with self._lock:
                if self.report is None:
                    self.started = True
                    self.report = await self._wind_up(reason)
                    with anyio.move_on_after(OFFLINE_TIMEOUT):
                        await self._vehicle.publish_state()
                result = self.report
        return result

    async def _wind_up(self, reason: str) -> ShutdownReport:
        vehicle = self._vehicle
        robot, progress, executor = vehicle.robot, vehicle.progress, vehicle.executor
        order_id = progress.order_id if progress.active or executor.moving else None
        failed = vehicle.actions.fail_unfinished(f"{reason}: the action was cancelled")
        problems: list[str] = []
        stopped: StopReport | None = None
        with anyio.move_on_after(SHUTDOWN_TIMEOUT) as deadline:
            with anyio.move_on_after(SHUTDOWN_STEP_TIMEOUT):  # the cancel's confirmation
                try:
                    await executor.cancel_order()
                except GalileoError as exc:
                    problems.append(f"cancel: {type(exc).__name__}: {exc}")
            status = robot.status
            docking = status is not None and status.charge_status in _DOCKING
            if docking and any(state.actionType == "startCharging" for state in failed):
                try:
                    await robot.stop_charging(timeout=SHUTDOWN_STEP_TIMEOUT)
                except GalileoError as exc:
                    problems.append(f"stopCharging: {type(exc).__name__}: {exc}")
            try:
                stopped = await robot.stop(timeout=SHUTDOWN_STEP_TIMEOUT)
            except GalileoError as exc:
                problems.append(f"stop: {type(exc).__name__}: {exc}")
            # The last state should show the vehicle standing (stop() may return first).
            with contextlib.suppress(GalileoError):
                await robot.wait_until(
                    lambda s: not report.driving(s), timeout=SHUTDOWN_STEP_TIMEOUT
                )
        if deadline.cancelled_caught:
            problems.append(f"the robot did not confirm its stop within {SHUTDOWN_TIMEOUT:g} s")
        failed_ids = tuple(state.actionId for state in failed)
        result = ShutdownReport(reason, order_id, failed_ids, stopped, tuple(problems))
        if order_id is not None or failed:
            refs = [reference("orderId", order_id)] if order_id is not None else []
            refs += [reference("actionId", action_id) for action_id in failed_ids]
            self.errors = [
                Error(
                    errorType="vehicleShutdown", errorLevel="WARNING",
                    errorDescription=f"{reason}: {result}", errorReferences=refs,
                )
            ]  # fmt: skip
        _log.info("%s: shut down (%s): %s", vehicle.config.serial_number, reason, result)
        vehicle.changed()
        return result
