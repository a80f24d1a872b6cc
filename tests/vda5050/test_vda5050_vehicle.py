"""A master control drives the VDA 5050 vehicle over a real Mosquitto against sim:// robots."""

from __future__ import annotations

import math
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from typing import Any

import anyio

import galileo_async as galileo
from galileo_async.robot import Robot
from galileo_async.vda5050 import Vehicle, VehicleConfig
from tests.support.vda5050_support import (
    Broker,
    Master,
    broker_fixture,  # noqa: F401 (the broker fixture)
    error_types,
    make_order,
    node,
)

FAST_SIM = "sim://?speed=20"


@asynccontextmanager
async def vehicle_on(
    broker: Broker, robot: Robot, serial: str = "r1", **options: Any
) -> AsyncIterator[Vehicle]:
    """A running Vehicle for ``robot`` (stopped on exit)."""
    config = VehicleConfig(broker=broker.url, manufacturer="acme", serial_number=serial, **options)
    vehicle = Vehicle(robot, config)
    async with anyio.create_task_group() as group:
        group.start_soon(vehicle.run)
        try:
            yield vehicle
        finally:
            group.cancel_scope.cancel()


@asynccontextmanager
async def driven_vehicle(
    broker: Broker, url: str = FAST_SIM, **options: Any
) -> AsyncIterator[tuple[Robot, Vehicle, Master]]:
    """A sim robot with navigation open, its vehicle and a master, all connected."""
    async with (
        Master.connected(broker) as master,
        galileo.connect(url) as robot,
        vehicle_on(broker, robot, **options) as vehicle,
    ):
        await robot.start_navigation()
        await master.wait_for("connection", lambda m: m["connectionState"] == "ONLINE")
        await master.wait_for("state", lambda s: s["operatingMode"] == "AUTOMATIC")
        yield robot, vehicle, master


def near(state: dict[str, Any], x: float, y: float, tolerance: float = 0.1) -> bool:
    position = state.get("agvPosition")
    return position is not None and math.hypot(position["x"] - x, position["y"] - y) < tolerance


async def test_three_node_order_by_coordinates(broker: Broker) -> None:
    async with driven_vehicle(broker) as (_, _vehicle, master):
        factsheet = await master.wait_for("factsheet", lambda m: True)
        assert "cancelOrder" in [
            a["actionType"] for a in factsheet["protocolFeatures"]["agvActions"]
        ]
        await master.order(
            "o1", [node("start", 0.0, 0.0), node("a", 1.0, 0.0), node("b", 1.0, 1.0)]
        )
        first = await master.next_state(lambda s: s["orderId"] == "o1")
        assert first["lastNodeId"] == "start"
        assert [n["nodeId"] for n in first["nodeStates"]] == ["a", "b"]
        halfway = await master.next_state(lambda s: s["lastNodeId"] == "a")
        assert [n["nodeId"] for n in halfway["nodeStates"]] == ["b"]
        assert halfway["lastNodeSequenceId"] == 2
        done = await master.next_state(lambda s: s["lastNodeId"] == "b" and not s["driving"])
        assert done["nodeStates"] == []
        assert done["edgeStates"] == []
        assert near(done, 1.0, 1.0)
        assert done["errors"] == []
        assert master.received["visualization"]


def action_status(state: dict[str, Any], action_id: str) -> str | None:
    for action in state["actionStates"]:
        if action["actionId"] == action_id:
            return str(action["actionStatus"])
    return None


async def test_pause_resume_and_cancel(broker: Broker) -> None:
    async with driven_vehicle(broker, "sim://?speed=3") as (robot, _vehicle, master):
        await master.order("o1", [node("start", 0.0, 0.0), node("far", 4.0, 3.0)])
        await master.next_state(lambda s: s["driving"])
        await master.instant(("p1", "startPause"))
        paused = await master.next_state(lambda s: action_status(s, "p1") == "FINISHED")
        assert paused["paused"] is True
        statuses = [action_status(s, "p1") for s in master.received["state"]]
        assert statuses.index("WAITING") < statuses.index("RUNNING") < statuses.index("FINISHED")
        await master.next_state(lambda s: not s["driving"])
        await master.instant(("r1", "stopPause"))
        resumed = await master.next_state(lambda s: action_status(s, "r1") == "FINISHED")
        assert resumed["paused"] is False
        if not resumed["driving"]:
            await master.next_state(lambda s: s["driving"], since=resumed)
        await master.instant(("c1", "cancelOrder"))
        cancelled = await master.next_state(lambda s: action_status(s, "c1") == "FINISHED")
        assert cancelled["nodeStates"] == []
        assert cancelled["edgeStates"] == []
        assert robot.status is not None
        assert not robot.status.goal_active
        assert cancelled["lastNodeId"] == "start"
        await master.instant(("c2", "cancelOrder"))
        again = await master.next_state(lambda s: action_status(s, "c2") == "FAILED")
        assert "noOrderToCancel" in error_types(again)


async def test_order_by_target_number(broker: Broker) -> None:
    async with driven_vehicle(broker) as (_, _vehicle, master):
        await master.order("o1", [node("here", 0.0, 0.0), node("1")])  # map target 1 is at (4, 3)
        done = await master.next_state(
            lambda s: s["lastNodeId"] == "1" and not s["nodeStates"] and not s["driving"]
        )
        assert near(done, 4.0, 3.0), done["agvPosition"]
        assert done["errors"] == []


def malformed_orders() -> list[tuple[dict[str, Any], str, tuple[str, str]]]:
    """(order, errorType, one expected errorReference)."""
    good = [node("start", 0.0, 0.0), node("a", 1.0, 0.0)]
    unjoined = make_order("bad1", good)
    unjoined["edges"][0]["endNodeId"] = "elsewhere"
    gap = make_order("bad2", good)
    gap["nodes"][1]["sequenceId"] = 4
    trajectory = make_order("bad3", good)
    trajectory["edges"][0]["trajectory"] = {
        "degree": 1, "knotVector": [0, 1], "controlPoints": [{"x": 0, "y": 0}, {"x": 1, "y": 0}]
    }  # fmt: skip
    pick = make_order("bad4", good)
    pick["nodes"][1]["actions"] = [{"actionId": "x1", "actionType": "pick", "blockingType": "HARD"}]
    other_map = make_order("bad5", [node("start", 0.0, 0.0), node("a", 1.0, 0.0)])
    other_map["nodes"][1]["nodePosition"]["mapId"] = "hall2"
    faraway = make_order("bad6", [node("start", 3.0, 3.0), node("a", 1.0, 0.0)])
    return [
        (unjoined, "validationError", ("edgeId", "estart-a")),
        (gap, "validationError", ("nodeId", "a")),
        (trajectory, "orderError", ("field", "trajectory")),
        (pick, "orderError", ("actionType", "pick")),
        (other_map, "orderError", ("mapId", "hall2")),
        (faraway, "noRouteError", ("nodeId", "start")),
    ]


async def test_malformed_orders_are_rejected_and_nothing_moves(broker: Broker) -> None:
    async with driven_vehicle(broker) as (robot, _vehicle, master):
        await master.send("order", {"orderId": "no-nodes", "orderUpdateId": 0}, validate=False)
        state = await master.next_state(lambda s: bool(s["errors"]))
        assert error_types(state) == ["validationError"]
        for order, error_type, reference in malformed_orders():
            await master.send("order", order)
            state = await master.next_state(
                lambda s, o=order: any(
                    {"referenceKey": "orderId", "referenceValue": o["orderId"]}
                    in e.get("errorReferences", []) for e in s["errors"]
                )
            )  # fmt: skip
            error = state["errors"][-1]  # the earlier rejections stay until an order is accepted
            assert error["errorType"] == error_type
            assert error["errorLevel"] == "WARNING"
            key, value = reference
            assert {"referenceKey": key, "referenceValue": value} in error["errorReferences"]
            assert state["orderId"] == ""
            assert state["nodeStates"] == []
            assert robot.status is not None
            assert not robot.status.goal_active
        await master.order("ok", [node("start", 0.0, 0.0), node("a", 0.5, 0.0)])
        accepted = await master.next_state(lambda s: s["orderId"] == "ok")
        assert accepted["errors"] == []


async def test_horizon_waits_for_an_update_stitched_at_the_base_end(broker: Broker) -> None:
    async with driven_vehicle(broker) as (_, _vehicle, master):
        nodes = [node("s", 0.0, 0.0), node("a", 1.0, 0.0), node("b", 1.0, 1.0, released=False)]
        await master.send("order", make_order("o1", nodes))
        waiting = await master.next_state(lambda s: s["lastNodeId"] == "a" and not s["driving"])
        assert waiting["newBaseRequest"] is True
        assert [(n["nodeId"], n["released"]) for n in waiting["nodeStates"]] == [("b", False)]
        not_stitched = [node("s", 0.0, 0.0), node("b", 1.0, 1.0)]  # must start at a (seq 2)
        await master.send("order", make_order("o1", not_stitched, update=1))
        refused = await master.next_state(lambda s: "orderUpdateError" in error_types(s))
        assert refused["orderUpdateId"] == 0
        update = make_order("o1", [node("a", 1.0, 0.0), node("b", 1.0, 1.0)], 2, first_seq=2)
        await master.send("order", update)
        await master.send("order", update)  # resent: ignored
        done = await master.next_state(lambda s: s["lastNodeId"] == "b")
        assert done["orderUpdateId"] == 2
        assert done["nodeStates"] == []
        assert done["lastNodeSequenceId"] == 4
        assert not done.get("newBaseRequest")
        await master.send("order", make_order("o1", [node("b", 1.0, 1.0)], 1, first_seq=4))
        lower = await master.next_state(lambda s: "orderUpdateError" in error_types(s))
        assert lower["orderUpdateId"] == 2


async def test_instant_actions_navigation_and_unknown(broker: Broker) -> None:
    async with driven_vehicle(broker) as (robot, _vehicle, master):
        await master.instant(("s1", "stateRequest"), ("f1", "factsheetRequest"), ("x", "lift"))
        failed = await master.next_state(lambda s: action_status(s, "x") == "FAILED")
        assert action_status(failed, "s1") == action_status(failed, "f1") == "FINISHED"
        [error] = [e for e in failed["errors"] if e["errorType"] == "unsupportedAction"]
        assert {"referenceKey": "actionId", "referenceValue": "x"} in error["errorReferences"]
        assert len(master.received["factsheet"]) >= 2
        await master.instant(("n0", "stopNavigation"))
        manual = await master.next_state(lambda s: action_status(s, "n0") == "FINISHED")
        await master.next_state(lambda s: s["operatingMode"] == "MANUAL")
        assert robot.status is not None
        assert not robot.status.navigating
        await master.order("o1", [node("start", 0.0, 0.0), node("a", 1.0, 0.0)])
        refused = await master.next_state(lambda s: "orderError" in error_types(s))
        assert refused["orderId"] == ""
        assert manual is not None


async def test_a_goal_the_planner_gives_up_fails_the_order(broker: Broker) -> None:
    async with driven_vehicle(broker, FAST_SIM + "&planner_abort=1") as (_, _vehicle, master):
        await master.order("o1", [node("start", 0.0, 0.0), node("a", 4.0, 3.0), node("b", 0, 1)])
        failed = await master.next_state(lambda s: "navigationError" in error_types(s))
        [error] = [e for e in failed["errors"] if e["errorType"] == "navigationError"]
        assert error["errorLevel"] == "WARNING"
        assert "GoalAborted" in error["errorDescription"]
        references = {(r["referenceKey"], r["referenceValue"]) for r in error["errorReferences"]}
        assert references == {("orderId", "o1"), ("nodeId", "a"), ("edgeId", "estart-a")}
        assert failed["nodeStates"] == []
        assert failed["lastNodeId"] == "start"


async def test_charging_actions(broker: Broker) -> None:
    async with driven_vehicle(broker) as (_, _vehicle, master):
        await master.instant(("c1", "startCharging"))
        started = await master.next_state(lambda s: action_status(s, "c1") == "FINISHED")
        if not started["batteryState"]["charging"]:
            await master.next_state(lambda s: s["batteryState"]["charging"], since=started)
        await master.instant(("c2", "stopCharging"))
        stopped = await master.next_state(lambda s: action_status(s, "c2") == "FINISHED")
        if stopped["batteryState"]["charging"]:
            await master.next_state(lambda s: not s["batteryState"]["charging"], since=stopped)
