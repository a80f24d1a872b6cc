"""Pydantic models of the VDA 5050 2.0 messages the vehicle reads and writes.

Field names are the standard's JSON names (camelCase) so that a model dumps to a message
that validates against the official JSON schemas.
"""

from __future__ import annotations

from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

__all__ = [
    "VERSION",
    "VERSIONS",
    "Action",
    "ActionParameter",
    "ActionState",
    "ActionStatus",
    "AgvPosition",
    "BatteryState",
    "BlockingType",
    "Connection",
    "ConnectionState",
    "Edge",
    "EdgeState",
    "Error",
    "ErrorLevel",
    "ErrorReference",
    "Factsheet",
    "Header",
    "Info",
    "InstantActions",
    "MapState",
    "Node",
    "NodePosition",
    "NodeState",
    "OperatingMode",
    "Order",
    "SafetyState",
    "State",
    "Velocity",
    "Visualization",
    "reference",
]

#: The protocol version the vehicle speaks by default (the ``version`` field of every message).
VERSION = "2.0.0"
#: ``vda_version`` → the ``version`` field: the versions this vehicle speaks.
VERSIONS = {"2.0": "2.0.0", "2.1": "2.1.0"}

BlockingType = Literal["NONE", "SOFT", "HARD"]
ActionStatus = Literal["WAITING", "INITIALIZING", "RUNNING", "PAUSED", "FINISHED", "FAILED"]
ErrorLevel = Literal["WARNING", "FATAL"]
OperatingMode = Literal["AUTOMATIC", "SEMIAUTOMATIC", "MANUAL", "SERVICE", "TEACHIN"]
ConnectionState = Literal["ONLINE", "OFFLINE", "CONNECTIONBROKEN"]

# Strict: "true" is not a boolean and "3" not a number, as the schemas say; unknown keys pass.
_STRICT_IN = ConfigDict(extra="ignore", strict=True)


class Header(BaseModel):
    """The header every message starts with."""

    headerId: int = Field(ge=0)
    timestamp: str
    version: str
    manufacturer: str
    serialNumber: str


# --- master control → vehicle -------------------------------------------------------------


class ActionParameter(BaseModel):
    """One key/value parameter of an action."""

    model_config = _STRICT_IN
    key: str
    value: Any


class Action(BaseModel):
    """An action of a node, an edge or an instantActions message."""

    model_config = _STRICT_IN
    actionType: str
    actionId: str
    actionDescription: str | None = None
    blockingType: BlockingType
    actionParameters: list[ActionParameter] | None = None


class NodePosition(BaseModel):
    """Where a node is in the map frame (metres, radians)."""

    model_config = _STRICT_IN
    x: float
    y: float
    theta: float | None = Field(default=None, ge=-3.14159265359, le=3.14159265359)
    allowedDeviationXY: float | None = Field(default=None, ge=0)
    allowedDeviationTheta: float | None = Field(default=None, ge=0, le=3.141592654)
    mapId: str
    mapDescription: str | None = None


class Node(BaseModel):
    """A node of an order."""

    model_config = _STRICT_IN
    nodeId: str
    sequenceId: int = Field(ge=0)
    nodeDescription: str | None = None
    released: bool
    nodePosition: NodePosition | None = None
    actions: list[Action]


class Edge(BaseModel):
    """An edge of an order, from startNodeId to endNodeId."""

    model_config = _STRICT_IN
    edgeId: str
    sequenceId: int = Field(ge=0)
    edgeDescription: str | None = None
    released: bool
    startNodeId: str
    endNodeId: str
    maxSpeed: float | None = None
    maxHeight: float | None = None
    minHeight: float | None = None
    orientation: float | None = None
    orientationType: Literal["GLOBAL", "TANGENTIAL"] | None = None
    direction: str | None = None
    rotationAllowed: bool | None = None
    maxRotationSpeed: float | None = None
    length: float | None = None
    trajectory: dict[str, Any] | None = None
    corridor: dict[str, Any] | None = None  # 2.1
    actions: list[Action]


class Order(Header):
    """An order: nodes and the edges between them, base (released) then horizon."""

    model_config = _STRICT_IN
    orderId: str
    orderUpdateId: int = Field(ge=0)
    zoneSetId: str | None = None
    nodes: list[Node]
    edges: list[Edge]


class InstantActions(Header):
    """Actions to run at once, under ``actions`` (§6.9) or ``instantActions`` (vda-5050-lib)."""

    model_config = _STRICT_IN
    actions: list[Action]
    #: True when the actions came under the key ``instantActions`` instead of ``actions``.
    other_key: bool = Field(default=False, exclude=True)

    @model_validator(mode="before")
    @classmethod
    def _either_key(cls, data: Any) -> Any:
        if not isinstance(data, dict):
            return data
        other = "actions" not in data and "instantActions" in data
        return (
            {**data, "actions": data["instantActions"], "other_key": True}
            if other
            else {**data, "other_key": False}
        )


# --- vehicle → master control -------------------------------------------------------------


class NodeState(BaseModel):
    """A node still to be traversed."""

    nodeId: str
    sequenceId: int
    nodeDescription: str | None = None
    nodePosition: NodePosition | None = None
    released: bool


class EdgeState(BaseModel):
    """An edge still to be traversed."""

    edgeId: str
    sequenceId: int
    edgeDescription: str | None = None
    released: bool


class AgvPosition(BaseModel):
    """The vehicle's pose in the map frame."""

    x: float
    y: float
    theta: float
    mapId: str
    positionInitialized: bool
    localizationScore: float | None = None


class Velocity(BaseModel):
    """The vehicle's velocity in its own frame (m/s, rad/s)."""

    vx: float | None = None
    vy: float | None = None
    omega: float | None = None


class ActionState(BaseModel):
    """The state of one action the vehicle received."""

    actionId: str
    actionType: str | None = None
    actionDescription: str | None = None
    actionStatus: ActionStatus
    resultDescription: str | None = None


class BatteryState(BaseModel):
    """Battery charge (percent, estimated), voltage and charging flag."""

    batteryCharge: float
    batteryVoltage: float | None = None
    charging: bool


def reference(key: str, value: str) -> ErrorReference:
    """An error or information reference ``key``: ``value``."""
    return ErrorReference(referenceKey=key, referenceValue=value)


class ErrorReference(BaseModel):
    """What an error or information is about (e.g. ``orderId``: ``"o1"``)."""

    referenceKey: str
    referenceValue: str


class Error(BaseModel):
    """An error the vehicle reports."""

    errorType: str
    errorReferences: list[ErrorReference] = Field(default_factory=list)
    errorDescription: str | None = None
    errorHint: str | None = None  # 2.1
    errorLevel: ErrorLevel


class Info(BaseModel):
    """An information entry the vehicle reports."""

    infoType: str
    infoReferences: list[ErrorReference] = Field(default_factory=list)
    infoDescription: str | None = None
    infoLevel: Literal["INFO", "DEBUG"]


class MapState(BaseModel):
    """A map stored on the vehicle (2.1 state.maps)."""

    mapId: str
    mapVersion: str
    mapDescription: str | None = None
    mapStatus: Literal["ENABLED", "DISABLED"]


class SafetyState(BaseModel):
    """Emergency stop and protective field state."""

    eStop: Literal["AUTOACK", "MANUAL", "REMOTE", "NONE"] = "NONE"
    fieldViolation: bool = False


class State(Header):
    """The state message."""

    orderId: str
    orderUpdateId: int
    lastNodeId: str
    lastNodeSequenceId: int
    nodeStates: list[NodeState]
    edgeStates: list[EdgeState]
    agvPosition: AgvPosition | None = None
    velocity: Velocity | None = None
    driving: bool
    paused: bool | None = None
    newBaseRequest: bool | None = None
    actionStates: list[ActionState]
    batteryState: BatteryState
    operatingMode: OperatingMode
    errors: list[Error]
    information: list[Info] | None = None
    safetyState: SafetyState
    maps: list[MapState] | None = None  # 2.1


class Visualization(Header):
    """Pose and velocity at a higher rate than state."""

    agvPosition: AgvPosition | None = None
    velocity: Velocity | None = None


class Connection(Header):
    """ONLINE, OFFLINE, or CONNECTIONBROKEN (the last will)."""

    connectionState: ConnectionState


class Factsheet(Header):
    """What the vehicle is and supports (sections as the standard lays them out)."""

    typeSpecification: dict[str, Any]
    physicalParameters: dict[str, Any]
    protocolLimits: dict[str, Any]
    protocolFeatures: dict[str, Any]
    agvGeometry: dict[str, Any]
    loadSpecification: dict[str, Any]
