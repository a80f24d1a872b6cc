"""Drives the released nodes of an order with the public Robot API; pause, resume, cancel."""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
from collections.abc import AsyncIterator, Callable

import anyio

from ..errors import GalileoError, GalileoTimeout
from ..models import TargetStatus
from ..robot import Robot
from . import report
from .models import Edge, Error, ErrorReference, Info, Node, reference
from .order import OrderProgress, target_number

__all__ = ["CANCEL_STOP_TIMEOUT", "NODE_TURN_TIMEOUT", "Executor", "can_limit_speed"]

_log = logging.getLogger(__name__)

#: Seconds the turn in place to a node's theta may take (then the order fails:
#: navigationTimeout); an order's own limit, not Robot.rotate_to's ROTATE_TIMEOUT.
NODE_TURN_TIMEOUT = 10.0
#: Seconds cancelOrder waits for the robot to stand still after its goal is cancelled
#: (then the action FAILED: the order is deleted all the same).
CANCEL_STOP_TIMEOUT = 10.0


def can_limit_speed(robot: Robot) -> bool:
    """True when ``robot``'s link can set a navigation speed (an edge maxSpeed is honoured)."""
    return robot.http is not None


class Executor:
    """Runs one vehicle's order: node after released node, until none is left."""

    def __init__(self, robot: Robot, progress: OrderProgress, changed: Callable[[], None]) -> None:
        self.robot = robot
        self.progress = progress
        self._changed = changed
        self._wake = asyncio.Event()
        self._idle = asyncio.Event()
        self._idle.set()
        self._scope: anyio.CancelScope | None = None
        #: The vehicle is paused (startPause): no node is started until stopPause.
        self.paused = False
        #: cancelOrder runs: no node is started, the order is deleted once the robot stands.
        self.cancelling = False
        #: Why the order ended short, reported until the next accepted order.
        self.errors: list[Error] = []
        self.information: list[Info] = []

    @property
    def moving(self) -> bool:
        """True while a node is being driven to."""
        return not self._idle.is_set()

    def wake(self) -> None:
        """Look for a released node to drive to (after an order, an update or a resume)."""
        self._wake.set()

    async def run(self) -> None:
        """Drive released nodes as they come; runs until cancelled."""
        while True:
            await self._wake.wait()
            self._wake.clear()
            while (
                not self.paused
                and not self.cancelling
                and (step := self.progress.next_step()) is not None
            ):
                await self._drive_step(*step)

    async def _drive_step(self, edge: Edge, node: Node) -> None:
        order_id = self.progress.order_id
        self._idle.clear()
        self._changed()
        try:
            with anyio.CancelScope() as scope:
                self._scope = scope
                async with self._speed_limit(edge):
                    await self._drive(node)
                self.progress.reached(node)
        except GalileoError as exc:
            stale = self.progress.order_id != order_id or not self.progress.active
            if stale or self.cancelling:
                return  # cancelled or failed meanwhile: that already said why
            _log.info("order %s failed at node %s: %s", order_id, node.nodeId, exc)
            self.fail(
                "navigationError" if not isinstance(exc, GalileoTimeout) else "navigationTimeout",
                f"node {node.nodeId}: {type(exc).__name__}: {exc}",
                [reference("orderId", order_id), reference("nodeId", node.nodeId),
                 reference("edgeId", edge.edgeId)],
            )  # fmt: skip
        finally:
            self._scope = None
            self._idle.set()
            self._changed()

    @contextlib.asynccontextmanager
    async def _speed_limit(self, edge: Edge) -> AsyncIterator[None]:
        """While driving ``edge``: navigation speed at most its maxSpeed, then as before."""
        http = self.robot.http
        if edge.maxSpeed is None or http is None:
            yield
            return
        previous = await http.navigation_speed()
        if edge.maxSpeed >= previous:
            yield
            return
        await http.set_navigation_speed(edge.maxSpeed)
        try:
            yield
        finally:
            with anyio.CancelScope(shield=True):
                try:
                    await http.set_navigation_speed(previous)
                except GalileoError as exc:
                    _log.warning("navigation speed not restored to %g m/s: %s", previous, exc)

    async def _drive(self, node: Node) -> None:
        position = node.nodePosition
        if position is None:
            target = target_number(node.nodeId)
            assert target is not None  # check_order let only map target numbers through
            await self.robot.goto(target)
            return
        await self.robot.goto_point(position.x, position.y)
        if position.theta is not None:
            # By velocity, not 'a': firmware ignores the rotate command (docs/protocol.md §2.g).
            await self.robot.turn_to(math.degrees(position.theta), timeout=NODE_TURN_TIMEOUT)

    def fail(self, error_type: str, description: str, refs: list[ErrorReference]) -> None:
        """End the order short with a WARNING error naming why."""
        self.errors.append(
            Error(
                errorType=error_type, errorLevel="WARNING", errorDescription=description,
                errorReferences=refs,
            )
        )  # fmt: skip
        self.progress.clear()
        self._changed()

    async def stop_driving(self) -> None:
        """Abandon the node being driven to (its goal is cancelled on exit) and wait for it."""
        if self._scope is not None:
            self._scope.cancel()
        await self._idle.wait()

    async def cancel_order(self) -> None:
        """cancelOrder (§6.6.3): stop the robot, then delete the order; returns once it stands.

        The order stays in the state until the robot stands, so the state that first shows
        it deleted is the one whose cancelOrder is FINISHED. GalileoTimeout when the robot
        does not stand within CANCEL_STOP_TIMEOUT s; the order is deleted on every exit.
        """
        self.cancelling = True
        self.paused = False
        try:
            await self.stop_driving()
            status = self.robot.status
            if status is not None and status.goal_active:
                await self.robot.cancel()
            if report.driving(self.robot.status):
                await self.robot.wait_until(
                    lambda s: not report.driving(s), timeout=CANCEL_STOP_TIMEOUT
                )
        finally:
            self.cancelling = False
            self.progress.clear()
            self._changed()

    async def pause(self) -> None:
        """startPause: no next node; a working goal is paused (i 0)."""
        self.paused = True
        self._changed()
        status = self.robot.status
        if status is not None and status.target_status == TargetStatus.WORKING:
            await self.robot.pause()

    async def resume(self) -> None:
        """stopPause: a paused goal resumes (i 1), and the next released node is started."""
        status = self.robot.status
        if status is not None and status.target_status == TargetStatus.PAUSED:
            await self.robot.resume()
        self.paused = False
        self._changed()
        self.wake()

    def new_order(self) -> None:
        """An order was accepted: earlier order errors end, driving starts."""
        self.errors.clear()
        self.information.clear()
        self._changed()
        self.wake()
