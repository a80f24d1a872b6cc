"""Vehicle: one robot as a VDA 5050 2.0 vehicle (state, orders, actions) over its Session."""

from __future__ import annotations

import contextlib
import logging
import zlib
from collections.abc import Hashable, Iterable
from typing import Any

import anyio
from pydantic import BaseModel, ValidationError

from ..errors import DuplicateVehicle, GalileoError, InvalidArgument
from ..models import GalileoStatus, LinkState, TargetStatus, VisualStatus
from ..robot import Robot
from . import report
from .actions import ActionRunner
from .config import VehicleConfig
from .execution import Executor, can_limit_speed
from .models import (
    VERSIONS,
    Connection,
    ConnectionState,
    Error,
    Factsheet,
    InstantActions,
    MapState,
    Order,
    State,
    Visualization,
    reference,
)
from .order import OrderProgress, Rejection, check_order
from .session import Session
from .shutdown import Shutdown, ShutdownReport
from .visualization import KEEP_ALIVE, clock

__all__ = [
    "MAX_ORDER_ERRORS",
    "NAVIGATION_RETRY_INITIAL",
    "NAVIGATION_RETRY_MAX",
    "Vehicle",
    "can_limit_speed",
    "run_vehicles",
]

_log = logging.getLogger(__name__)
#: Order rejections kept in state.errors (the newest) until an order is accepted.
MAX_ORDER_ERRORS = 10
#: Seconds --start-navigation waits before it tries again after a failed start, doubled
#: after each failure up to NAVIGATION_RETRY_MAX.
NAVIGATION_RETRY_INITIAL = 2.0
NAVIGATION_RETRY_MAX = 60.0

#: The link states in which the robot is unreachable, each with the name of the event that
#: reports it (the robotLinkLost error's reference).
_LINK_DOWN = {LinkState.STALE: "LinkStale", LinkState.LOST: "ConnectionLost"}


class Vehicle:
    """A VDA 5050 vehicle for ``robot``: ``await vehicle.run()`` until cancelled."""

    def __init__(self, robot: Robot, config: VehicleConfig) -> None:
        if not isinstance(config, VehicleConfig):
            # Only its type: a mapping passed instead could hold the password.
            raise InvalidArgument(f"config must be a VehicleConfig, got a {type(config).__name__}")
        self.robot = robot
        self.config = config
        self.progress = OrderProgress()
        self.executor = Executor(robot, self.progress, self.changed)
        self.actions = ActionRunner(self)
        self.session = Session(
            config, self._connection, self._on_connect, self._on_message, self.shut_down
        )
        self._group: anyio.abc.TaskGroup | None = None
        self._headers: dict[str, int] = {}
        self._dirty = anyio.Event()
        self._order_errors: list[Error] = []
        self._link_error: Error | None = None
        self._navigation_error: Error | None = None
        #: The robot link came back: --start-navigation looks at navigation again.
        self._link_returned = False
        self._other_key_logged = False
        self._shutdown = Shutdown(self)
        #: The significant part of the last status seen (report.significant).
        self._significant: Hashable = object()
        #: What the last visualization was made of (_motion), and when it went out.
        self._visualized: tuple[Hashable, float] | None = None

    # --- what the vehicle reports ------------------------------------------------------

    @property
    def connected(self) -> bool:
        """True while the MQTT session is up."""
        return self.session.connected

    async def wait_online(self) -> None:
        """Return once the MQTT session is up (at once if it is)."""
        await self.session.wait_online()

    async def wait_offline(self) -> None:
        """Return once the MQTT session is down (at once if it is)."""
        await self.session.wait_offline()

    def changed(self) -> None:
        """Something that matters changed: publish a state message soon."""
        self._dirty.set()

    def _header(self, topic: str) -> dict[str, Any]:
        header_id = self._headers.get(topic, -1) + 1
        self._headers[topic] = header_id
        return {
            "headerId": header_id, "timestamp": report.timestamp(),
            "version": VERSIONS[self.config.vda_version],
            "manufacturer": self.config.manufacturer, "serialNumber": self.config.serial_number,
        }  # fmt: skip

    def errors(self) -> list[Error]:
        """state.errors: the link, the order, the actions, the status."""
        link = [e for e in (self._link_error, self._navigation_error) if e is not None]
        return [
            *link, *self._shutdown.errors, *self._order_errors, *self.executor.errors,
            *self.actions.errors, *report.status_errors(self.robot.status),
        ]  # fmt: skip

    def state(self) -> State:
        """The state message as of now (the header is counted)."""
        status = self.robot.status
        progress = self.progress
        paused = self.executor.paused or (
            status is not None and status.target_status == TargetStatus.PAUSED
        )
        v21 = self.config.vda_version == "2.1"
        maps = [MapState(mapId=self.config.map_id, mapVersion="current", mapStatus="ENABLED")]
        return State(
            **self._header("state"),
            orderId=progress.order_id, orderUpdateId=progress.order_update_id,
            lastNodeId=progress.last_node_id, lastNodeSequenceId=progress.last_node_sequence_id,
            nodeStates=progress.node_states(), edgeStates=progress.edge_states(),
            agvPosition=report.agv_position(status, self.config.map_id),
            velocity=report.velocity(status), driving=report.driving(status), paused=paused,
            newBaseRequest=progress.new_base_request, actionStates=self.actions.states(),
            batteryState=report.battery_state(status),
            operatingMode=report.operating_mode(status),
            errors=report.with_hints(self.errors()) if v21 else self.errors(),
            information=list(self.executor.information),
            safetyState={"eStop": "NONE", "fieldViolation": False}, maps=maps if v21 else None,
        )  # fmt: skip

    def factsheet(self) -> Factsheet:
        """The factsheet message (the header is counted)."""
        sections = report.factsheet_sections(
            self.config, list(report.INSTANT_ACTIONS), max_speed=can_limit_speed(self.robot)
        )
        return Factsheet(**self._header("factsheet"), **sections)

    # --- publishing ----------------------------------------------------------------------

    async def publish(
        self, topic: str, message: BaseModel, *, qos: int = 0, retain: bool = False
    ) -> bool:
        """Publish ``message`` on the vehicle's ``topic``; False when the broker is away."""
        return await self.session.publish(topic, message, qos=qos, retain=retain)

    async def publish_state(self) -> None:
        """Publish a state message now."""
        await self.publish("state", self.state())

    async def publish_factsheet(self) -> None:
        """Publish the factsheet (retained)."""
        await self.publish("factsheet", self.factsheet(), retain=True)

    def _connection(self, state: ConnectionState) -> Connection:
        return Connection(**self._header("connection"), connectionState=state)

    async def _on_connect(self) -> None:
        await self.publish_factsheet()
        await self.publish_state()

    def _on_message(self, topic: str, payload: bytes) -> None:
        if topic == "order":
            self.on_order(payload)
        elif topic == "instantActions" and self._group is not None:
            self.on_instant_actions(payload, self._group)

    # --- incoming --------------------------------------------------------------------------

    def on_order(self, payload: bytes) -> None:
        """Check an order and take it over, or report why not (state.errors)."""
        try:
            order = Order.model_validate_json(payload)
        except ValidationError as exc:
            self._reject(Rejection("validationError", _first_problem(exc), [("topic", "order")]))
            return
        try:
            if self.closing:
                raise Rejection(
                    "orderError", "the vehicle is shutting down: it takes no more orders",
                    [("orderId", order.orderId)],
                )  # fmt: skip
            check_order(
                order, map_id=self.config.map_id, max_speed=self.config.max_speed,
                can_limit_speed=can_limit_speed(self.robot),
            )  # fmt: skip
            status = self.robot.status
            if self._link_error is not None or status is None or not status.navigating:
                raise Rejection(
                    "orderError",
                    "the vehicle cannot drive: "
                    + ("its robot link is lost" if self._link_error else "navigation is closed"),
                    [("orderId", order.orderId), ("operatingMode", report.operating_mode(status))],
                )
            if self.robot.map_targets is None and any(n.nodePosition for n in order.nodes[1:]):
                raise Rejection(
                    "orderError",
                    "nodes by position need the number of map targets (--map-targets)",
                    [("orderId", order.orderId), ("field", "nodePosition")],
                )
            pose = status.pose
            position = (pose.x, pose.y) if pose is not None else None
            decision = self.progress.decide(
                order, position, self.config.default_deviation_xy,
                actions_running=self.actions.running, map_id=self.config.map_id,
                theta=pose.theta if pose is not None else None,
            )  # fmt: skip
            if decision == "stitch" and self.executor.cancelling:
                raise Rejection(
                    "orderUpdateError",
                    f"order {order.orderId} is being cancelled (cancelOrder runs): send a new "
                    "order once it is FINISHED",
                    [("orderId", order.orderId), ("orderUpdateId", str(order.orderUpdateId))],
                )
        except Rejection as exc:
            self._reject(exc)
            return
        if decision == "ignore":
            return
        self.progress.accept(order, decision)
        self._order_errors = []
        self.actions.forget_finished()
        self.executor.new_order()

    def _reject(self, rejection: Rejection) -> None:
        _log.info("%s: order rejected: %s", self.config.serial_number, rejection)
        # Kept until an order is accepted (§6.6.4.1): a later rejection does not hide one.
        self._order_errors = [*self._order_errors, rejection.error][-MAX_ORDER_ERRORS:]
        self.changed()

    def on_instant_actions(self, payload: bytes, group: anyio.abc.TaskGroup) -> None:
        """Queue the actions of an instantActions message (WAITING), run them in order."""
        try:
            message = InstantActions.model_validate_json(payload)
        except ValidationError as exc:
            self.actions.add_error(
                Rejection("validationError", _first_problem(exc), [("topic", "instantActions")])
            )
            self.changed()
            return
        if self.closing:
            self.actions.add_error(
                Rejection(
                    "vehicleShutdown", "the vehicle is shutting down: it runs no more actions",
                    [("actionId", action.actionId) for action in message.actions],
                )
            )  # fmt: skip
            self.changed()
            return
        if message.other_key and not self._other_key_logged:
            self._other_key_logged = True
            _log.warning(
                "%s: instant actions came under the key 'instantActions' (VDA 5050 2.0 §6.9 "
                "says 'actions'); accepted", self.config.serial_number,
            )  # fmt: skip
        self.actions.queue(message.actions)
        group.start_soon(self.actions.run, message.actions)

    # --- tasks ----------------------------------------------------------------------------

    async def run(self) -> None:
        """Be the vehicle until cancelled; then shut_down(), OFFLINE, and the session closed.

        DuplicateVehicle (everything stopped) when another vehicle with this identity was
        on the broker first: that one stays connected.
        """
        # A listener, not a task: a task would wake with each of the robot's 30 statuses/s.
        self.robot.add_update_listener(self._on_status)
        if self.robot.status is not None:
            self._on_status(self.robot.status)
        try:
            await self._run()
        finally:
            self.robot.remove_update_listener(self._on_status)

    async def _run(self) -> None:
        duplicate: DuplicateVehicle | None = None
        async with anyio.create_task_group() as group:
            group.start_soon(self.executor.run)
            group.start_soon(self._watch_link)
            group.start_soon(self._publish_states)
            if self.config.broker_loss_stop_delay is not None:
                group.start_soon(self._broker_watchdog, self.config.broker_loss_stop_delay)
            visualizations = clock()
            if self.config.visualization_rate > 0:
                # Each vehicle its own phase: many vehicles on one loop must not publish at once.
                phase = zlib.crc32(self.config.topic("").encode()) % 1000 / 1000
                visualizations.add(
                    self, 1.0 / self.config.visualization_rate, self._visualize, phase
                )
            if self.config.start_navigation:
                group.start_soon(self._keep_navigation)
            self._group = group
            try:
                await self.session.run()
            except DuplicateVehicle as exc:
                _log.error("%s: %s", self.config.serial_number, exc)
                duplicate = exc
                group.cancel_scope.cancel()
            except anyio.get_cancelled_exc_class():
                await self.shut_down()  # done before OFFLINE when the broker was there
                raise
            finally:
                self._group = None
                visualizations.remove(self)
        if duplicate is not None:
            raise duplicate

    # --- shutting down -----------------------------------------------------------------

    @property
    def shut_down_report(self) -> ShutdownReport | None:
        """What shut_down() did; None before it ran."""
        return self._shutdown.report

    @property
    def closing(self) -> bool:
        """True from the start of shut_down(): orders and instant actions are refused."""
        return self._shutdown.started

    async def shut_down(self, reason: str = "the vehicle shut down") -> ShutdownReport:
        """Stop being a vehicle: cancel the order as cancelOrder does, stop, say so in a state.

        The order is cancelled (§6.6.3: the robot stops, the order deleted, orderId kept),
        every action not yet finished FAILED with ``reason`` (running ones cancelled),
        Robot.stop() runs, and a state goes out (a ``vehicleShutdown`` WARNING names what
        was cut short); orders and actions are refused from then on (shutdown.py). Once,
        shielded, bounded. run() calls it when cancelled, before OFFLINE.
        """
        return await self._shutdown(reason)

    def _may_open_navigation(self, status: GalileoStatus) -> bool:
        """Nothing forbids opening navigation now: no order, no drive, no stop, link up."""
        return not (
            self.closing or self.actions.navigation_stopped or self.progress.active
            or self.executor.moving or report.driving(status) or self._link_error is not None
        )  # fmt: skip

    async def _keep_navigation(self) -> None:
        """--start-navigation: open navigation now and whenever the robot comes back closed.

        Again after a robot restart (the link UP again, or navigation closed after it was
        open), with back-off on failure; never while an order or a drive runs, after the
        master's stopNavigation, or once the vehicle shuts down.
        """
        serial = self.config.serial_number
        wanted, was_open, delay = True, False, NAVIGATION_RETRY_INITIAL
        async for status in self.robot.statuses():
            if self._link_returned:
                self._link_returned, wanted = False, True
            if status.navigating:
                wanted, was_open = False, True
                continue
            if was_open:
                was_open, wanted = False, True
                if not self.actions.navigation_stopped:
                    _log.warning("%s: the robot's navigation closed (a restart?)", serial)
            if not wanted or not self._may_open_navigation(status):
                continue
            _log.warning("%s: opening the robot's navigation (--start-navigation)", serial)
            try:
                await self.robot.start_navigation()
            except GalileoError as exc:
                self._navigation_error = Rejection("startNavigationFailed", str(exc), []).error
                self.changed()
                _log.warning("%s: navigation did not open: %s; retry in %g s",
                             serial, exc, delay)  # fmt: skip
                await anyio.sleep(delay)
                delay = min(delay * 2, NAVIGATION_RETRY_MAX)
                continue
            _log.info("%s: navigation is open", serial)
            self._navigation_error = None
            wanted, was_open, delay = False, True, NAVIGATION_RETRY_INITIAL
            self.changed()

    def _on_status(self, status: GalileoStatus) -> None:
        """Each status (synchronously, from the robot's store): a state when it matters."""
        key = report.significant(status)
        if key != self._significant:
            self._significant = key
            self.changed()

    async def _watch_link(self) -> None:
        async for state in self.robot.link_states():
            if state in _LINK_DOWN:
                self._link_error = Error(
                    errorType="robotLinkLost", errorLevel="FATAL",
                    errorDescription=f"the link to the robot is down: {state.value}",
                    errorReferences=[reference("link", _LINK_DOWN[state])],
                )  # fmt: skip
                await self.executor.stop_driving()
                if self.progress.active:
                    self.executor.fail(
                        "orderFailed", "the robot link was lost while the order ran",
                        [reference("orderId", self.progress.order_id)],
                    )  # fmt: skip
                self.changed()
            elif state is LinkState.UP and self._link_error is not None:
                self._link_error = None
                self._link_returned = True
                self.changed()

    async def _publish_states(self) -> None:
        while True:
            with anyio.move_on_after(self.config.state_interval):
                await self._dirty.wait()
            self._dirty = anyio.Event()
            await self.publish_state()

    def _visualize(self, now: float) -> None:
        """The clock's call: a visualization, unless unchanged for less than KEEP_ALIVE s.

        VDA 5050 2.0 and 2.1 §6.13: the vehicle "can broadcast" its position and velocity,
        at a rate the integrator defines; an unchanged one is repeated once a second only.
        """
        if not self.session.connected:
            self._visualized = None  # the first after a reconnect goes out
            return
        motion = _motion(self.robot.status)
        last = self._visualized
        if last is not None and last[0] == motion and now - last[1] < KEEP_ALIVE:
            return
        # One validation of the whole message: its parts from what _motion read.
        fields = self._header("visualization")
        if motion is not None:
            x, y, theta, vx, omega, navigating, visual = motion
            initialized = navigating and visual == VisualStatus.TRACKING
            fields["agvPosition"] = report.agv_position_fields(
                x, y, theta, initialized, self.config.map_id
            )
            fields["velocity"] = report.velocity_fields(vx, omega)
        if self.session.publish_now("visualization", Visualization.model_validate(fields)):
            self._visualized = (motion, now)

    async def _broker_watchdog(self, delay: float) -> None:
        while True:
            await self.session.wait_offline()
            with anyio.move_on_after(delay):
                await self.session.wait_online()
                continue
            if self.progress.active or self.executor.moving:
                _log.warning("%s: broker gone, cancelling the order", self.config.serial_number)
                self.executor.errors.append(
                    Error(
                        errorType="brokerLost", errorLevel="WARNING",
                        errorDescription=f"the broker was unreachable for "
                        f"{delay:g} s: the order was cancelled",
                        errorReferences=[reference("orderId", self.progress.order_id)],
                    )
                )  # fmt: skip
                with contextlib.suppress(GalileoError):
                    await self.executor.cancel_order()
            await self.session.wait_online()


def _motion(
    status: GalileoStatus | None,
) -> tuple[float | None, float | None, float | None, float | None, float | None, bool,
           VisualStatus | None] | None:  # fmt: skip
    """What a visualization is made of (report.agv_position and report.velocity)."""
    if status is None:
        return None
    return (
        status.current_pose_x, status.current_pose_y, status.current_angle,
        status.current_speed_x, status.current_speed_theta, status.navigating,
        status.visual_status,
    )  # fmt: skip


def _first_problem(exc: ValidationError) -> str:
    problem = exc.errors()[0]
    where = ".".join(str(part) for part in problem["loc"]) or "message"
    return f"{where}: {problem['msg']} ({exc.error_count()} problem(s))"


async def run_vehicles(vehicles: Iterable[Vehicle]) -> None:
    """Run many vehicles on this event loop, each with its own MQTT session, until cancelled."""
    async with anyio.create_task_group() as group:
        for vehicle in vehicles:
            group.start_soon(vehicle.run)
