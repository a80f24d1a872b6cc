"""instantActions: actionStates WAITING → RUNNING → FINISHED / FAILED, and their handlers."""

from __future__ import annotations

import logging
from collections.abc import Awaitable, Callable
from typing import Protocol

import anyio

from ..errors import GalileoError
from ..models import ChargeStatus
from ..robot import Robot
from .execution import Executor
from .models import Action, ActionState, ActionStatus, Error
from .order import OrderProgress, Rejection

__all__ = [
    "CHARGE_TIMEOUT",
    "MAP_ACTIONS",
    "MAX_ACTION_ERRORS",
    "MAX_ENDED_ACTIONS",
    "ActionRunner",
    "VehicleHost",
]

_log = logging.getLogger(__name__)

#: Errors of failed actions kept in state.errors (the newest); a new order clears them.
MAX_ACTION_ERRORS = 10
#: The map actions of VDA 5050 2.1 (they need the robot's HTTP API: FAILED on this link).
MAP_ACTIONS = ("downloadMap", "enableMap", "deleteMap")
#: Seconds startCharging may take from the command to charging (docking included).
CHARGE_TIMEOUT = 120.0
#: Ended actions kept in state.actionStates (the newest) when no order clears them.
MAX_ENDED_ACTIONS = 50


class VehicleHost(Protocol):
    """What the actions use of their vehicle (vehicle.Vehicle is one)."""

    @property
    def robot(self) -> Robot:
        """The robot the vehicle drives."""

    @property
    def executor(self) -> Executor:
        """The vehicle's order executor."""

    @property
    def progress(self) -> OrderProgress:
        """The vehicle's order progress."""

    def changed(self) -> None:
        """The state changed: publish it soon."""

    async def publish_state(self) -> None:
        """Publish the state now."""

    async def publish_factsheet(self) -> None:
        """Publish the factsheet now."""


class ActionRunner:
    """Runs one vehicle's instant actions and remembers their states."""

    def __init__(self, vehicle: VehicleHost) -> None:
        self._vehicle = vehicle
        self._states: dict[str, ActionState] = {}
        self.errors: list[Error] = []
        #: The scopes of the running run() calls (fail_unfinished cancels them).
        self._scopes: set[anyio.CancelScope] = set()
        #: After fail_unfinished: the states stay as they are.
        self._closed = False
        robot, executor = vehicle.robot, vehicle.executor
        self._handlers: dict[str, Callable[[], Awaitable[object]]] = {
            "startPause": executor.pause,
            "stopPause": executor.resume,
            "stateRequest": vehicle.publish_state,
            "factsheetRequest": vehicle.publish_factsheet,
            "startCharging": self._start_charging,
            "stopCharging": robot.stop_charging,
            "startNavigation": self._start_navigation,
            "stopNavigation": self._stop_navigation,
        }
        #: The master closed navigation (stopNavigation) and has not opened it since:
        #: --start-navigation leaves it closed.
        self.navigation_stopped = False

    async def _start_navigation(self) -> None:
        self.navigation_stopped = False
        await self._vehicle.robot.start_navigation()

    async def _stop_navigation(self) -> None:
        self.navigation_stopped = True
        await self._vehicle.robot.stop_navigation()

    async def _start_charging(self) -> None:
        """Dock and charge: FINISHED only once the robot charges (RUNNING while it docks)."""
        robot = self._vehicle.robot
        await robot.start_charging()
        status = await robot.wait_until(
            lambda s: s.charging or s.charge_status == ChargeStatus.ERROR, timeout=CHARGE_TIMEOUT
        )
        if not status.charging:
            raise Rejection(
                "chargingFailed", "the robot reported a charging error while docking",
                [("charge_status", str(int(ChargeStatus.ERROR)))],
            )  # fmt: skip

    def states(self) -> list[ActionState]:
        """state.actionStates."""
        return list(self._states.values())

    @property
    def running(self) -> bool:
        """True while an action is neither FINISHED nor FAILED (WAITING and PAUSED count)."""
        return any(s.actionStatus not in ("FINISHED", "FAILED") for s in self._states.values())

    def add_error(self, rejection: Rejection) -> None:
        """Report ``rejection`` in state.errors (the newest MAX_ACTION_ERRORS are kept)."""
        self.errors = [*self.errors, rejection.error][-MAX_ACTION_ERRORS:]

    def forget_finished(self) -> None:
        """A new order: finished and failed actions and their errors leave the state."""
        self._states = {
            key: state
            for key, state in self._states.items()
            if state.actionStatus not in ("FINISHED", "FAILED")
        }
        self.errors = []

    def fail_unfinished(self, description: str) -> list[ActionState]:
        """Every action not yet FINISHED or FAILED becomes FAILED, the running ones cancelled.

        What cancelOrder does to an order's actions (VDA 5050 §6.6.3), for a vehicle that
        shuts down: nothing runs or changes a state afterwards. Returns the states failed.
        """
        self._closed = True
        for scope in self._scopes:
            scope.cancel()
        failed = []
        for key, state in self._states.items():
            if state.actionStatus not in ("FINISHED", "FAILED"):
                failed.append(state)
                self._states[key] = state.model_copy(
                    update={"actionStatus": "FAILED", "resultDescription": description}
                )
        self._vehicle.changed()
        return failed

    def _set(self, action: Action, status: ActionStatus, result: str | None = None) -> None:
        if self._closed:
            return
        self._states[action.actionId] = ActionState(
            actionId=action.actionId, actionType=action.actionType,
            actionDescription=action.actionDescription, actionStatus=status,
            resultDescription=result,
        )  # fmt: skip
        ended = [k for k, v in self._states.items() if v.actionStatus in ("FINISHED", "FAILED")]
        for key in ended[:-MAX_ENDED_ACTIONS]:
            del self._states[key]
        self._vehicle.changed()

    def queue(self, actions: list[Action]) -> None:
        """Show every action of a message as WAITING."""
        for action in actions:
            self._set(action, "WAITING")

    async def run(self, actions: list[Action]) -> None:
        """Run ``actions`` one after the other; each state they pass through is published."""
        with anyio.CancelScope() as scope:
            self._scopes.add(scope)
            try:
                # Published here, not only by the coalescing publisher: a master sees every step.
                await self._vehicle.publish_state()
                for action in actions:
                    await self._run_one(action)
            finally:
                self._scopes.discard(scope)

    async def _run_one(self, action: Action) -> None:
        self._set(action, "RUNNING")
        await self._vehicle.publish_state()
        try:
            await self._dispatch(action)
        except Rejection as exc:
            self.add_error(exc)
            self._set(action, "FAILED", str(exc))
        except GalileoError as exc:
            _log.info("action %s (%s) failed: %s", action.actionId, action.actionType, exc)
            self.add_error(
                Rejection(
                    "actionFailed", f"{action.actionType}: {type(exc).__name__}: {exc}",
                    [("actionId", action.actionId), ("actionType", action.actionType)],
                )
            )  # fmt: skip
            self._set(action, "FAILED", f"{type(exc).__name__}: {exc}")
        else:
            self._set(action, "FINISHED")
        await self._vehicle.publish_state()

    async def _dispatch(self, action: Action) -> None:
        refs = [("actionId", action.actionId), ("actionType", action.actionType)]
        if action.actionType == "cancelOrder":
            executor = self._vehicle.executor
            if not (self._vehicle.progress.active or executor.moving):
                raise Rejection("noOrderToCancel", "there is no order to cancel", refs)
            if executor.cancelling:
                raise Rejection("noOrderToCancel", "the order is being cancelled already", refs)
            await executor.cancel_order()
            return
        if action.actionType in MAP_ACTIONS:
            raise Rejection(
                "unsupportedAction",
                f"{action.actionType}: this vehicle cannot manage the robot's maps (the robot's "
                "HTTP API can; this link does not reach it)",
                refs,
            )  # fmt: skip
        handler = self._handlers.get(action.actionType)
        if handler is None:
            raise Rejection(
                "unsupportedAction",
                f"instant action {action.actionType!r} is not supported on this vehicle",
                refs,
            )
        await handler()
