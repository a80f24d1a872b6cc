"""Galileo status → VDA 5050 state parts, and the factsheet: pure, no I/O."""

from __future__ import annotations

import functools
import math
from collections.abc import Hashable, Sequence
from datetime import datetime, timezone
from typing import Any

from ..battery import battery_charge
from ..models import GalileoStatus, TargetStatus, VisualStatus
from .config import VehicleConfig
from .models import AgvPosition, BatteryState, Error, ErrorReference, Velocity

__all__ = [
    "ERROR_HINTS",
    "INSTANT_ACTIONS",
    "agv_position",
    "agv_position_fields",
    "battery_state",
    "driving",
    "factsheet_sections",
    "operating_mode",
    "significant",
    "status_errors",
    "timestamp",
    "velocity",
    "velocity_fields",
    "with_hints",
]

#: instantActions this vehicle runs, with what each does (also the factsheet's agvActions).
INSTANT_ACTIONS: dict[str, str] = {
    "startPause": "Pause the vehicle (the running goal is paused, no next node is started).",
    "stopPause": "Resume after startPause.",
    "cancelOrder": "Stop at once and delete the order.",
    "stateRequest": "Publish a state message now.",
    "factsheetRequest": "Publish the factsheet now.",
    "startCharging": "Drive to the dock and charge.",
    "stopCharging": "Stop charging and leave the dock.",
    "startNavigation": "Open navigation (custom): the vehicle becomes AUTOMATIC.",
    "stopNavigation": "Close navigation (custom): the vehicle becomes MANUAL.",
}


#: VDA 5050 2.1 errorHint by errorType: how the master control can resolve the error.
ERROR_HINTS: dict[str, str] = {
    "validationError": "send a message that follows the JSON schema of this version",
    "orderError": "leave out what the factsheet does not list (actions, fields, maps)",
    "orderUpdateError": "start an update at the end of the current base; send a new orderId "
    "once the order and the actions ended (or after cancelOrder)",
    "noRouteError": "start the order where the vehicle stands (within allowedDeviationXY)",
    "unsupportedAction": "use an action the factsheet lists in agvActions",
    "noOrderToCancel": "nothing to do: the vehicle has no order",
    "robotLinkLost": "check the robot's serial, network or ROS link",
    "visualLost": "drive the robot back into the mapped area or restart navigation",
    "vehicleShutdown": "the vehicle was stopped on purpose: send orders once it is ONLINE again",
}


def with_hints(errors: list[Error]) -> list[Error]:
    """``errors`` with an errorHint (2.1) where ERROR_HINTS has one."""
    return [
        e.model_copy(update={"errorHint": ERROR_HINTS[e.errorType]})
        if e.errorHint is None and e.errorType in ERROR_HINTS else e
        for e in errors
    ]  # fmt: skip


def timestamp() -> str:
    """Now as ISO 8601 UTC with milliseconds (``2026-11-24T22:00:00.000Z``)."""
    now = datetime.now(timezone.utc)
    return now.strftime("%Y-%m-%dT%H:%M:%S.") + f"{now.microsecond // 1000:03d}Z"


def battery_state(status: GalileoStatus | None) -> BatteryState:
    """batteryState from ``power`` (volts) and ``charge_status``."""
    volts = status.power if status is not None else None
    charging = status.charging if status is not None else False
    if volts is None or not math.isfinite(volts):
        return BatteryState(batteryCharge=0.0, charging=charging)
    return BatteryState(
        batteryCharge=battery_charge(volts), batteryVoltage=round(volts, 3), charging=charging
    )


def _wrap(theta: float) -> float:
    return math.atan2(math.sin(theta), math.cos(theta))


def agv_position(status: GalileoStatus | None, map_id: str) -> AgvPosition | None:
    """agvPosition; positionInitialized when navigation is open and the camera tracks."""
    fields = agv_position_fields(*_pose_parts(status), map_id)
    return None if fields is None else AgvPosition(**fields)


def _pose_parts(
    status: GalileoStatus | None,
) -> tuple[float | None, float | None, float | None, bool]:
    if status is None:
        return None, None, None, False
    initialized = status.navigating and status.visual_status == VisualStatus.TRACKING
    return status.current_pose_x, status.current_pose_y, status.current_angle, initialized


def agv_position_fields(
    x: float | None, y: float | None, theta: float | None, initialized: bool, map_id: str
) -> dict[str, Any] | None:
    """agv_position's fields from the status's pose (None: unknown, as GalileoStatus.pose)."""
    if x is None or y is None or theta is None or (x == -1.0 and y == -1.0 and theta == -1.0):
        return None
    return {
        "x": round(x, 4), "y": round(y, 4), "theta": round(_wrap(theta), 4), "mapId": map_id,
        "positionInitialized": initialized,
    }  # fmt: skip


def velocity(status: GalileoStatus | None) -> Velocity | None:
    """Velocity in the vehicle frame (a differential drive: vy is 0)."""
    if status is None:
        return None
    fields = velocity_fields(status.current_speed_x, status.current_speed_theta)
    return None if fields is None else Velocity(**fields)


def velocity_fields(vx: float | None, omega: float | None) -> dict[str, Any] | None:
    """velocity's fields from the status's speeds (None without a forward speed)."""
    if vx is None:
        return None
    return {"vx": round(vx, 4), "vy": 0.0, "omega": round(omega, 4) if omega is not None else None}


def driving(status: GalileoStatus | None) -> bool:
    """True while the wheels turn (the robot's own speeds, not the commanded ones)."""
    if status is None:
        return False
    return (
        abs(status.current_speed_x or 0.0) > 1e-3 or abs(status.current_speed_theta or 0.0) > 1e-3
    )


def operating_mode(status: GalileoStatus | None) -> str:
    """AUTOMATIC while navigation is open (orders can run), else MANUAL."""
    return "AUTOMATIC" if status is not None and status.navigating else "MANUAL"


def status_errors(status: GalileoStatus | None) -> list[Error]:
    """Errors read off the status itself: the camera lost its tracking while navigating."""
    if status is None or not status.navigating or status.visual_status != VisualStatus.LOST:
        return []
    return [
        Error(
            errorType="visualLost", errorLevel="WARNING",
            errorDescription="the visual system lost its tracking; the robot cannot localise",
            errorReferences=[ErrorReference(referenceKey="visual_status", referenceValue="2")],
        )
    ]  # fmt: skip


@functools.lru_cache(maxsize=1024)
def _battery_step(volts: float) -> float:
    # A robot's voltage takes few float32 values: most statuses find theirs here.
    return round(battery_charge(volts), 0)


def significant(status: GalileoStatus | None) -> Hashable:
    """The part of a status whose change makes a new state message (not pose or speed).

    Called with each status (30 a second per vehicle): driving() inlined, the battery step
    cached by voltage.
    """
    if status is None:
        return None
    speed, turn, volts = status.current_speed_x, status.current_speed_theta, status.power
    return (
        status.nav_status, status.visual_status, status.charge_status, status.map_status,
        status.target_status == TargetStatus.PAUSED,
        abs(speed or 0.0) > 1e-3 or abs(turn or 0.0) > 1e-3,
        None if volts is None else _battery_step(volts),
    )  # fmt: skip


def factsheet_sections(
    config: VehicleConfig,
    action_types: Sequence[str],
    *,
    theta: bool = True,
    max_speed: bool = False,
) -> dict[str, dict[str, object]]:
    """The factsheet's sections (typeSpecification … loadSpecification) of a Galileo robot.

    ``theta``: node orientations are honoured; ``max_speed``: edge maxSpeed is (both listed
    in optionalParameters).
    """
    # No blockingTypes: the 2.0 schema puts its enum on the array itself, so no list validates.
    actions = [
        {
            "actionType": name,
            "actionDescription": INSTANT_ACTIONS[name],
            "actionScopes": ["INSTANT"],
        }
        for name in action_types
    ]
    rate = config.visualization_rate
    timing: dict[str, float] = {"minOrderInterval": 0.0, "minStateInterval": 0.0}
    if rate > 0:
        timing["visualizationInterval"] = 1.0 / rate  # the interval actually published
    optional = [
        {
            "parameter": "order.nodes.nodePosition",
            "support": "SUPPORTED",
            "description": 'without it, a nodeId that is a map target number ("3")',
        },
    ]
    if theta:
        optional.append({"parameter": "order.nodes.nodePosition.theta", "support": "SUPPORTED"})
    if max_speed:
        optional.append(
            {
                "parameter": "order.edges.maxSpeed",
                "support": "SUPPORTED",
                "description": "through the navigation speed of the HTTP API",
            }
        )
    return {
        "typeSpecification": {
            "seriesName": "Galileo",
            "seriesDescription": f"Galileo visual navigation robot (map {config.map_id})",
            "agvKinematic": "DIFF",
            "agvClass": "CARRIER",
            "maxLoadMass": 0.0,
            "localizationTypes": ["NATURAL"],
            "navigationTypes": ["AUTONOMOUS"],
        },
        "physicalParameters": {
            "speedMin": 0.0,
            "speedMax": config.max_speed,
            "accelerationMax": config.acceleration_max,
            "decelerationMax": config.deceleration_max,
            "heightMin": config.height_min,
            "heightMax": config.height_max,
            "width": config.width,
            "length": config.length,
        },
        "protocolLimits": {
            "maxStringLens": {"idNumericalOnly": False},
            # Node and edge actions and trajectories are refused outright: no length is
            # declared for them, since 0 would mean "no limit".
            "maxArrayLens": {},
            "timing": timing,
        },
        "protocolFeatures": {
            "optionalParameters": optional,
            "agvActions": actions,
        },
        "agvGeometry": {},
        "loadSpecification": {},
    }
