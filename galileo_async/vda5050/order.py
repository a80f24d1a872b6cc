"""Order validation and the vehicle's order memory (stitching, traversal): pure, no I/O."""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Literal

from .models import Edge, EdgeState, Error, ErrorReference, Node, NodeState, Order

__all__ = [
    "MAX_KNOWN_NODES",
    "MAX_TARGET_NUMBER",
    "OrderProgress",
    "Rejection",
    "check_order",
    "target_number",
]

#: Map target numbers the goto command accepts (docs/protocol.md §2).
MAX_TARGET_NUMBER = 255
#: Node positions of accepted orders remembered (the newest) to name the nearest node.
MAX_KNOWN_NODES = 1000

Decision = Literal["ignore", "new", "stitch"]


class Rejection(Exception):
    """An order or action the vehicle refuses; ``error`` is what state.errors reports."""

    def __init__(
        self, error_type: str, description: str, references: Iterable[tuple[str, str]]
    ) -> None:
        super().__init__(description)
        self.error = Error(
            errorType=error_type,
            errorDescription=description,
            errorLevel="WARNING",
            errorReferences=[
                ErrorReference(referenceKey=k, referenceValue=v) for k, v in references
            ],
        )


def target_number(node_id: str) -> int | None:
    """The map target a position-less node names (``"3"`` → 3), or None."""
    if not node_id.isascii() or not node_id.isdigit():
        return None
    number = int(node_id)
    return number if number <= MAX_TARGET_NUMBER else None


def _order_refs(order: Order) -> list[tuple[str, str]]:
    return [("orderId", order.orderId), ("orderUpdateId", str(order.orderUpdateId))]


def _check_structure(order: Order) -> None:
    """Sequence ids, edges joining the nodes, base before horizon (validationError)."""
    refs = _order_refs(order)

    def invalid(message: str, *more: tuple[str, str]) -> Rejection:
        return Rejection("validationError", message, [*refs, *more])

    nodes, edges = order.nodes, order.edges
    if not nodes:
        raise invalid("an order needs at least one node")
    if len(edges) != len(nodes) - 1:
        raise invalid(f"{len(nodes)} nodes need {len(nodes) - 1} edges, got {len(edges)}")
    first = nodes[0].sequenceId
    if first % 2:
        raise invalid("node sequenceIds must be even", ("nodeId", nodes[0].nodeId))
    for index, node in enumerate(nodes):
        if node.sequenceId != first + 2 * index:
            raise invalid(
                f"node sequenceId {node.sequenceId} should be {first + 2 * index}",
                ("nodeId", node.nodeId),
            )
    for index, edge in enumerate(edges):
        start, end = nodes[index], nodes[index + 1]
        if edge.sequenceId != start.sequenceId + 1:
            raise invalid(
                f"edge sequenceId {edge.sequenceId} should be {start.sequenceId + 1}",
                ("edgeId", edge.edgeId),
            )
        if (edge.startNodeId, edge.endNodeId) != (start.nodeId, end.nodeId):
            raise invalid(
                f"edge {edge.edgeId} joins {edge.startNodeId} → {edge.endNodeId}, "
                f"not {start.nodeId} → {end.nodeId}",
                ("edgeId", edge.edgeId),
            )
        if edge.released != end.released:
            raise invalid(
                f"edge {edge.edgeId} and its end node {end.nodeId} must both be released or not",
                ("edgeId", edge.edgeId),
            )
    if not nodes[0].released:
        raise invalid("the first node must be released", ("nodeId", nodes[0].nodeId))
    released = [node.released for node in nodes]
    if released != sorted(released, reverse=True):
        horizon = next(n for n, r in zip(nodes, released, strict=True) if not r)
        raise invalid("a released node follows the horizon", ("nodeId", horizon.nodeId))


def _check_capabilities(order: Order, map_id: str) -> None:
    """Actions, trajectories, maps and nodes this vehicle cannot use (orderError)."""
    refs = _order_refs(order)
    items: list[tuple[str, Node | Edge]] = [
        *(("nodeId", node) for node in order.nodes),
        *(("edgeId", edge) for edge in order.edges),
    ]
    for key, item in items:
        name = item.nodeId if isinstance(item, Node) else item.edgeId
        for action in item.actions:
            raise Rejection(
                "orderError",
                f"{key} {name}: action {action.actionType!r} is not supported on this vehicle",
                [*refs, (key, name), ("actionId", action.actionId),
                 ("actionType", action.actionType)],
            )  # fmt: skip
    for edge in order.edges:
        if edge.corridor is not None:
            raise Rejection(
                "orderError",
                f"edge {edge.edgeId}: corridors are not supported (the robot plans its path)",
                [*refs, ("edgeId", edge.edgeId), ("field", "corridor")],
            )
        if edge.trajectory is not None:
            raise Rejection(
                "orderError",
                f"edge {edge.edgeId}: trajectories are not supported (the robot plans its path)",
                [*refs, ("edgeId", edge.edgeId), ("field", "trajectory")],
            )
    for node in order.nodes:
        position = node.nodePosition
        if position is None:
            if target_number(node.nodeId) is None:
                raise Rejection(
                    "orderError",
                    f"node {node.nodeId!r} has no nodePosition and is no map target number "
                    f"(0..{MAX_TARGET_NUMBER})",
                    [*refs, ("nodeId", node.nodeId)],
                )
        elif position.mapId != map_id:
            raise Rejection(
                "orderError",
                f"node {node.nodeId}: map {position.mapId!r} is not this vehicle's {map_id!r}",
                [*refs, ("nodeId", node.nodeId), ("mapId", position.mapId)],
            )


def _check_optional_fields(order: Order, max_speed: float, can_limit_speed: bool) -> None:
    """Optional fields the vehicle cannot honour (§6.6.4.2: orderError naming the field)."""
    refs = _order_refs(order)
    if order.zoneSetId is not None:
        raise Rejection(
            "orderError", "zones are not supported: zoneSetId cannot be honoured",
            [*refs, ("field", "zoneSetId")],
        )  # fmt: skip
    for edge in order.edges:
        speed = edge.maxSpeed
        if speed is not None and speed < max_speed and not can_limit_speed:
            raise Rejection(
                "orderError",
                f"edge {edge.edgeId}: maxSpeed {speed:g} m/s is below the robot's "
                f"{max_speed:g} m/s and this link cannot set the navigation speed",
                [*refs, ("edgeId", edge.edgeId), ("field", "maxSpeed")],
            )


def check_order(
    order: Order, *, map_id: str, max_speed: float = math.inf, can_limit_speed: bool = False
) -> None:
    """Raise Rejection (validationError, then orderError) unless this vehicle can drive it.

    An edge maxSpeed below ``max_speed`` needs ``can_limit_speed`` (a link that sets the
    navigation speed); a zoneSetId is always refused.
    """
    _check_structure(order)
    _check_capabilities(order, map_id)
    _check_optional_fields(order, max_speed, can_limit_speed)


@dataclass
class OrderProgress:
    """The order in the vehicle's buffer: what is left to traverse and the last node reached."""

    order_id: str = ""
    order_update_id: int = 0
    last_node_id: str = ""
    last_node_sequence_id: int = 0
    nodes: list[Node] = field(default_factory=list)
    edges: list[Edge] = field(default_factory=list)
    #: (x, y, mapId) of the nodes of accepted orders by nodeId (the newest MAX_KNOWN_NODES).
    known_nodes: dict[str, tuple[float, float, str]] = field(default_factory=dict)

    @property
    def active(self) -> bool:
        """True while nodes remain to be traversed (released or horizon)."""
        return bool(self.nodes)

    @property
    def new_base_request(self) -> bool:
        """True when the base is driven and only horizon nodes remain."""
        return self.active and not self.nodes[0].released

    def _base_end(self) -> tuple[str, int]:
        released = [node for node in self.nodes if node.released]
        if released:
            return released[-1].nodeId, released[-1].sequenceId
        return self.last_node_id, self.last_node_sequence_id

    def decide(
        self, order: Order, position: tuple[float, float] | None, default_deviation: float,
        *, actions_running: bool = False, theta: float | None = None, map_id: str = "",
    ) -> Decision:  # fmt: skip
        """What to do with a checked order: ignore (resent), new, stitch; else Rejection.

        ``actions_running``: an action of the vehicle is neither FINISHED nor FAILED (with
        nodes left, Figure 8's step 3: a new orderId is then an orderUpdateError).
        ``theta`` and ``map_id``: the rest of the vehicle's pose, named in a noRouteError.
        """
        refs = _order_refs(order)
        first = order.nodes[0]
        if order.orderId == self.order_id:
            if order.orderUpdateId < self.order_update_id:
                raise Rejection(
                    "orderUpdateError",
                    f"orderUpdateId {order.orderUpdateId} is lower than the current "
                    f"{self.order_update_id}",
                    refs,
                )
            if order.orderUpdateId == self.order_update_id:
                return "ignore"
        if order.orderId != self.order_id and (self.active or actions_running):
            # Figure 8, step 3: a new order waits until this one is done or cancelled.
            active = [("activeOrderId", self.order_id)] if self.order_id else []
            why = (
                f"order {self.order_id} is still running or waits for an update: cancel it "
                "first (cancelOrder) or update it"
                if self.active
                else "an action is still neither FINISHED nor FAILED: wait until it ends"
            )
            raise Rejection("orderUpdateError", why, [*refs, *active])
        if self.active or order.orderId == self.order_id:
            base_end = self._base_end()
            if (first.nodeId, first.sequenceId) == base_end:
                return "stitch"
            raise Rejection(
                "orderUpdateError",
                f"the update must start at the end of the current base, node {base_end[0]} "
                f"(sequenceId {base_end[1]}), of order {self.order_id}",
                [*refs, ("nodeId", first.nodeId)],
            )
        start = first.nodePosition
        if start is not None and position is not None:
            # Figure 8, step 4: within the first node's deviation range, whatever its name.
            allowed = start.allowedDeviationXY
            allowed = default_deviation if allowed is None else allowed
            if math.hypot(start.x - position[0], start.y - position[1]) <= allowed:
                return "new"
        elif first.nodeId == self.last_node_id and self.last_node_id:
            return "new"
        raise Rejection(
            "noRouteError",
            f"the first node {first.nodeId} is not where the vehicle stands: "
            + self._whereabouts(order, position, theta, map_id),
            [*refs, ("nodeId", first.nodeId)],
        )

    def _whereabouts(
        self, order: Order, position: tuple[float, float] | None, theta: float | None,
        map_id: str,
    ) -> str:  # fmt: skip
        """Where the vehicle is, and the nearest node it knows (this order's or an earlier's)."""
        if position is None:
            return "the vehicle's position is unknown"
        x, y = position
        where = f"the vehicle is at x {x:.3f} m, y {y:.3f} m"
        if theta is not None:
            where += f", theta {math.atan2(math.sin(theta), math.cos(theta)):.3f} rad"
        if map_id:
            where += f" on map {map_id}"
        candidates = dict(self.known_nodes)
        for node in order.nodes:
            if node.nodePosition is not None:
                p = node.nodePosition
                candidates[node.nodeId] = (p.x, p.y, p.mapId)
        distances = [
            (math.hypot(nx - x, ny - y), node_id)
            for node_id, (nx, ny, node_map) in candidates.items()
            if not map_id or node_map == map_id
        ]
        if distances:
            distance, nearest = min(distances)
            where += f"; the nearest node is {nearest}, {distance:.2f} m away"
        return where

    def accept(self, order: Order, decision: Decision) -> None:
        """Take ``order`` over: a new order starts at its first node (reached), a stitch appends."""
        if decision == "ignore":
            return
        if decision == "stitch":
            self.nodes = [node for node in self.nodes if node.released] + order.nodes[1:]
            self.edges = [edge for edge in self.edges if edge.released] + list(order.edges)
        else:
            first = order.nodes[0]
            self.last_node_id, self.last_node_sequence_id = first.nodeId, first.sequenceId
            self.nodes, self.edges = list(order.nodes[1:]), list(order.edges)
        self.order_id, self.order_update_id = order.orderId, order.orderUpdateId
        for node in order.nodes:
            if node.nodePosition is not None:
                p = node.nodePosition
                self.known_nodes.pop(node.nodeId, None)  # the newest last
                self.known_nodes[node.nodeId] = (p.x, p.y, p.mapId)
        for node_id in list(self.known_nodes)[:-MAX_KNOWN_NODES]:
            del self.known_nodes[node_id]

    def next_step(self) -> tuple[Edge, Node] | None:
        """The released edge and node to drive next, or None (done, or waiting for a base)."""
        if self.nodes and self.edges and self.nodes[0].released and self.edges[0].released:
            return self.edges[0], self.nodes[0]
        return None

    def reached(self, node: Node) -> None:
        """``node`` (the next one) was reached: it and its edge leave the states."""
        if self.nodes and self.nodes[0] is node:
            self.nodes.pop(0)
            self.edges.pop(0)
            self.last_node_id, self.last_node_sequence_id = node.nodeId, node.sequenceId

    def clear(self) -> None:
        """End the order (cancelled or failed): nothing left to traverse."""
        self.nodes, self.edges = [], []

    def node_states(self) -> list[NodeState]:
        """state.nodeStates."""
        return [
            NodeState(
                nodeId=n.nodeId,
                sequenceId=n.sequenceId,
                nodeDescription=n.nodeDescription,
                nodePosition=n.nodePosition,
                released=n.released,
            )
            for n in self.nodes
        ]

    def edge_states(self) -> list[EdgeState]:
        """state.edgeStates."""
        return [
            EdgeState(
                edgeId=e.edgeId,
                sequenceId=e.sequenceId,
                edgeDescription=e.edgeDescription,
                released=e.released,
            )
            for e in self.edges
        ]
