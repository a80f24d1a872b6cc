"""VDA 5050 2.0 conformance and interoperability: masters as they really send, §6 rules."""

from __future__ import annotations

import math
import re
import sys
import time
from datetime import datetime
from pathlib import Path
from typing import Any

import anyio
import pytest

import galileo_async as galileo
from galileo_async.errors import DuplicateVehicle
from galileo_async.vda5050 import Vehicle, VehicleConfig
from galileo_async.vda5050.session import YOUNG_SESSION
from tests.support.vda5050_support import (
    WAIT,
    Broker,
    Master,
    broker_fixture,  # noqa: F401 (the broker fixture)
    error_types,
    make_order,
    node,
)
from tests.vda5050.test_vda5050_vehicle import FAST_SIM, action_status, driven_vehicle

ROOT = Path(__file__).resolve().parents[2]


def references(state: dict[str, Any], error_type: str) -> set[tuple[str, str]]:
    """The (key, value) references of the newest error of ``error_type`` in ``state``."""
    errors = [e for e in state["errors"] if e["errorType"] == error_type]
    return {(r["referenceKey"], r["referenceValue"]) for r in errors[-1]["errorReferences"]}


async def lib_instant(master: Master, *actions: tuple[str, str]) -> None:
    """Instant actions shaped as vda-5050-lib 1.4.0 sends them for 2.0 (key instantActions)."""
    body = [
        {"actionId": a, "actionType": t, "blockingType": "HARD", "actionParameters": []}
        for a, t in actions
    ]
    await master.send("instantActions", {"instantActions": body}, validate=False)


async def test_instant_actions_as_vda_5050_lib_sends_them(broker: Broker) -> None:
    async with driven_vehicle(broker, "sim://?speed=3") as (robot, _vehicle, master):
        await lib_instant(master, ("s1", "stateRequest"))
        await master.next_state(lambda s: action_status(s, "s1") == "FINISHED")
        await master.order("o1", [node("start", 0.0, 0.0), node("far", 4.0, 3.0)])
        await master.next_state(lambda s: s["driving"])
        await lib_instant(master, ("p1", "startPause"))
        paused = await master.next_state(lambda s: action_status(s, "p1") == "FINISHED")
        assert paused["paused"] is True
        await lib_instant(master, ("r1", "stopPause"))
        await master.next_state(lambda s: action_status(s, "r1") == "FINISHED")
        await lib_instant(master, ("c1", "cancelOrder"))
        cancelled = await master.next_state(lambda s: action_status(s, "c1") == "FINISHED")
        assert cancelled["nodeStates"] == []
        assert "validationError" not in error_types(cancelled)
        assert robot.status is not None
        assert not robot.status.goal_active


async def test_an_edge_max_speed_or_a_zone_set_the_robot_cannot_honour_is_refused(
    broker: Broker,
) -> None:
    async with driven_vehicle(broker) as (robot, _vehicle, master):
        factsheet = await master.wait_for("factsheet", lambda m: True)
        honoured = [p["parameter"] for p in factsheet["protocolFeatures"]["optionalParameters"]]
        assert "order.edges.maxSpeed" not in honoured
        assert "order.zoneSetId" not in honoured
        slow = make_order("slow", [node("start", 0.0, 0.0), node("a", 2.0, 0.0)])
        slow["edges"][0]["maxSpeed"] = 0.1
        await master.send("order", slow)
        refused = await master.next_state(lambda s: "orderError" in error_types(s))
        assert ("field", "maxSpeed") in references(refused, "orderError")
        assert refused["orderId"] == ""
        zoned = dict(make_order("zoned", [node("start", 0.0, 0.0), node("a", 2.0, 0.0)]))
        zoned["zoneSetId"] = "hall-1"
        await master.send("order", zoned)
        refused = await master.next_state(
            lambda s: ("field", "zoneSetId") in references(s, "orderError")
            if "orderError" in error_types(s) else False
        )  # fmt: skip
        assert refused["orderId"] == ""
        assert robot.status is not None
        assert not robot.status.goal_active
        fast = make_order("fast", [node("start", 0.0, 0.0), node("a", 0.5, 0.0)])
        fast["edges"][0]["maxSpeed"] = 0.8  # the robot's top speed: honoured trivially
        await master.send("order", fast)
        done = await master.next_state(lambda s: s["lastNodeId"] == "a")
        assert done["orderId"] == "fast"


async def test_rejections_are_reported_until_an_order_is_accepted(broker: Broker) -> None:
    async with driven_vehicle(broker) as (_, _vehicle, master):
        await master.send("order", {"orderId": "no-nodes", "orderUpdateId": 0}, validate=False)
        await master.next_state(lambda s: "validationError" in error_types(s))
        faraway = make_order("far", [node("start", 3.0, 3.0), node("a", 1.0, 0.0)])
        await master.send("order", faraway)
        both = await master.next_state(lambda s: "noRouteError" in error_types(s))
        assert error_types(both) == ["validationError", "noRouteError"]
        assert not any("errorHint" in e for e in both["errors"])  # 2.1 only
        await master.order("ok", [node("start", 0.0, 0.0), node("a", 0.5, 0.0)])
        accepted = await master.next_state(lambda s: s["orderId"] == "ok")
        assert accepted["errors"] == []


async def test_a_new_order_while_one_waits_for_an_update_is_an_order_update_error(
    broker: Broker,
) -> None:
    # Figure 8, step 3, "waiting for an update": only horizon nodes are left.
    async with driven_vehicle(broker) as (_, _vehicle, master):
        nodes = [node("s", 0.0, 0.0), node("a", 1.0, 0.0), node("b", 1.0, 1.0, released=False)]
        await master.send("order", make_order("o1", nodes))
        await master.next_state(lambda s: s["lastNodeId"] == "a" and not s["driving"])
        other = make_order("o2", [node("a", 1.0, 0.0), node("c", 0.0, 1.0)], first_seq=2)
        await master.send("order", other)
        refused = await master.next_state(lambda s: "orderUpdateError" in error_types(s))
        assert ("orderId", "o2") in references(refused, "orderUpdateError")
        assert ("activeOrderId", "o1") in references(refused, "orderUpdateError")
        assert "orderError" not in error_types(refused)
        assert refused["orderId"] == "o1"
        assert [n["nodeId"] for n in refused["nodeStates"]] == ["b"]


async def test_a_new_order_while_one_drives_its_base_is_an_order_update_error(
    broker: Broker,
) -> None:
    # Figure 8, step 3, "still executing": released nodes are left; the order goes on.
    async with driven_vehicle(broker, "sim://?speed=3") as (robot, _vehicle, master):
        await master.order("o1", [node("start", 0.0, 0.0), node("far", 2.0, 0.0)])
        await master.next_state(lambda s: s["driving"])
        await master.order("o2", [node("start", 0.0, 0.0), node("b", 0.0, 1.0)])
        refused = await master.next_state(lambda s: "orderUpdateError" in error_types(s))
        assert ("orderId", "o2") in references(refused, "orderUpdateError")
        assert refused["orderId"] == "o1"
        assert [n["nodeId"] for n in refused["nodeStates"]] == ["far"]
        done = await master.next_state(lambda s: s["lastNodeId"] == "far")
        assert done["orderId"] == "o1"
        assert robot.status is not None


async def test_a_new_order_while_an_action_runs_is_an_order_update_error(
    broker: Broker,
) -> None:
    # Figure 8, step 3: no nodes left, but an action neither FINISHED nor FAILED (docking).
    async with driven_vehicle(broker, "sim://?speed=1") as (_, _vehicle, master):
        await master.order("o1", [node("start", 0.0, 0.0), node("a", 0.2, 0.0)])
        await master.next_state(lambda s: s["lastNodeId"] == "a" and not s["nodeStates"])
        await master.instant(("c1", "startCharging"))
        await master.next_state(lambda s: action_status(s, "c1") == "RUNNING")
        await master.order("o2", [node("a", 0.2, 0.0), node("b", 0.2, 0.5)])
        refused = await master.next_state(lambda s: "orderUpdateError" in error_types(s))
        assert ("orderId", "o2") in references(refused, "orderUpdateError")
        assert action_status(refused, "c1") == "RUNNING"
        assert refused["orderId"] == "o1"
        assert refused["nodeStates"] == []
        charging = await master.next_state(lambda s: action_status(s, "c1") == "FINISHED")
        assert charging["orderId"] == "o1"


async def test_a_new_order_from_the_last_node_the_vehicle_has_left_has_no_route(
    broker: Broker,
) -> None:
    async with driven_vehicle(broker, "sim://?speed=3") as (robot, _vehicle, master):
        await master.order("o1", [node("start", 0.0, 0.0), node("far", 4.0, 3.0)])
        await master.next_state(lambda s: s["driving"])
        await robot.wait_until(
            lambda s: s.pose is not None and math.hypot(s.pose.x, s.pose.y) > 1.0, timeout=WAIT
        )
        await master.instant(("c1", "cancelOrder"))
        cancelled = await master.next_state(lambda s: action_status(s, "c1") == "FINISHED")
        assert cancelled["lastNodeId"] == "start"
        await master.order("o2", [node("start", 0.0, 0.0), node("b", 0.0, 1.0)])
        refused = await master.next_state(lambda s: "noRouteError" in error_types(s))
        assert refused["orderId"] == "o1"
        # The description says where the vehicle is and which known node is nearest.
        [error] = [e for e in refused["errors"] if e["errorType"] == "noRouteError"]
        found = re.search(
            r"at x (\S+) m, y (\S+) m, theta (\S+) rad on map map; "
            r"the nearest node is (\w+), (\S+) m away",
            error["errorDescription"],
        )
        assert found is not None, error["errorDescription"]
        x, y, theta = (float(found[i]) for i in (1, 2, 3))
        position = refused["agvPosition"]
        assert math.hypot(x - position["x"], y - position["y"]) < 0.01
        assert abs(theta - position["theta"]) < 0.01
        nearest = min(("start", 0.0, 0.0), ("far", 4.0, 3.0), ("b", 0.0, 1.0),
                      key=lambda n: math.hypot(n[1] - x, n[2] - y))  # fmt: skip
        assert found[4] == nearest[0]
        away = math.hypot(nearest[1] - x, nearest[2] - y)
        assert float(found[5]) == pytest.approx(away, abs=0.01)
        assert robot.status is not None
        assert not robot.status.goal_active


async def test_start_charging_finishes_only_once_the_robot_charges(broker: Broker) -> None:
    async with driven_vehicle(broker, FAST_SIM) as (_, _vehicle, master):
        await master.instant(("c1", "startCharging"))
        running = await master.next_state(lambda s: action_status(s, "c1") == "RUNNING")
        assert not running["batteryState"]["charging"]
        finished = await master.next_state(lambda s: action_status(s, "c1") == "FINISHED")
        assert finished["batteryState"]["charging"] is True


async def test_without_a_broker_the_order_goes_on_and_the_vehicle_is_back_at_once(
    broker: Broker,
) -> None:
    # 5.6 m at 0.8 m/s and speed 1: about 7 s without the broker.
    async with driven_vehicle(broker, "sim://?speed=1") as (robot, vehicle, master):
        await master.order("o1", [node("start", 0.0, 0.0), node("far", 5.6, 0.0)])
        await master.next_state(lambda s: s["driving"])
        await broker.stop()
        await vehicle.wait_offline()
        await robot.wait_until(lambda s: not s.goal_active, timeout=WAIT)
        await broker.start()
        started = time.monotonic()
        with anyio.fail_after(WAIT):
            await vehicle.wait_online()
        back_after = time.monotonic() - started
        assert back_after < 1.0, back_after
        async with Master.connected(broker) as again:
            await again.instant(("s", "stateRequest"))
            state = await again.next_state(lambda s: action_status(s, "s") == "FINISHED")
            assert state["lastNodeId"] == "far"
            assert "brokerLost" not in error_types(state)


async def test_the_factsheet_tells_the_truth(broker: Broker) -> None:
    options = {"visualization_rate": 10.0, "width": 0.5, "length": 0.6, "height_max": 0.4}
    async with driven_vehicle(broker, FAST_SIM, **options) as (_, _vehicle, master):
        factsheet = await master.wait_for("factsheet", lambda m: True)
        timing = factsheet["protocolLimits"]["timing"]
        assert timing["visualizationInterval"] == 0.1
        assert 0 not in factsheet["protocolLimits"]["maxArrayLens"].values()
        physical = factsheet["physicalParameters"]
        assert (physical["width"], physical["length"], physical["heightMax"]) == (0.5, 0.6, 0.4)


async def test_theta_is_reached_on_firmware_that_ignores_the_rotate_command(
    broker: Broker,
) -> None:
    async with driven_vehicle(broker, "sim://?speed=5") as (robot, _vehicle, master):
        await master.order("o1", [node("start", 0.0, 0.0), node("a", 0.5, 0.0, theta=1.55)])
        done = await master.next_state(lambda s: s["lastNodeId"] == "a")
        assert done["errors"] == []
        assert not done.get("information")
        assert abs(done["agvPosition"]["theta"] - 1.55) <= math.radians(robot.angle_tolerance)


async def established(master: Master) -> None:
    """Return once the vehicle has been connected longer than YOUNG_SESSION.

    By the visualizations' own timestamps: a vehicle standing still sends one a second only.
    """
    first = await master.wait_for("visualization", lambda m: True)
    since = _stamp(first) + YOUNG_SESSION + 0.5
    await master.wait_for("visualization", lambda m: _stamp(m) >= since)


def _stamp(message: dict[str, Any]) -> float:
    return datetime.fromisoformat(message["timestamp"].replace("Z", "+00:00")).timestamp()


async def test_a_duplicate_vehicle_stops_and_leaves_the_first_connected(broker: Broker) -> None:
    async with driven_vehicle(broker, FAST_SIM) as (_, first, master):
        await established(master)
        async with galileo.connect(FAST_SIM) as other:
            config = VehicleConfig(broker=broker.url, manufacturer="acme", serial_number="r1")
            second = Vehicle(other, config)
            with anyio.fail_after(WAIT), pytest.raises(DuplicateVehicle, match="acme/r1"):
                await second.run()
        await first.wait_online()
        await master.instant(("s", "stateRequest"))
        await master.next_state(lambda s: action_status(s, "s") == "FINISHED")
        connections = [m["connectionState"] for m in master.received["connection"]]
        assert connections[-1] == "ONLINE"
        assert connections.count("CONNECTIONBROKEN") <= 2, connections  # one takeover each
        assert first.connected


async def test_the_cli_of_a_duplicate_vehicle_exits_10(broker: Broker, tmp_path: Path) -> None:
    async with driven_vehicle(broker, FAST_SIM) as (_, first, master):
        await established(master)
        with anyio.fail_after(WAIT):
            proc = await anyio.run_process(
                [sys.executable, "-m", "galileo_async", "--port", FAST_SIM, "vda5050",
                 "--broker", broker.url, "--manufacturer", "acme", "--serial-number", "r1"],
                check=False, cwd=ROOT,
            )  # fmt: skip
        assert proc.returncode == 10, proc.stderr
        assert b"DuplicateVehicle" in proc.stderr
        await first.wait_online()


async def test_the_first_state_without_the_cancelled_order_shows_cancel_order_finished(
    broker: Broker,
) -> None:
    # vda-5050-lib: "processed by cancellation" is read off the first state that shows the
    # order processed (no nodes, no edges); §6.6.3: FINISHED once the vehicle stands.
    async with driven_vehicle(broker, "sim://?speed=1") as (robot, _vehicle, master):
        await master.order("o1", [node("start", 0.0, 0.0), node("far", 5.0, 0.0)])
        await robot.wait_until(lambda s: (s.current_speed_x or 0.0) > 0.5, timeout=WAIT)
        await master.instant(("c1", "cancelOrder"))
        running = await master.next_state(lambda s: action_status(s, "c1") == "RUNNING")
        processed = await master.next_state(
            lambda s: not s["nodeStates"] and not s["edgeStates"], since=running
        )
        assert action_status(processed, "c1") == "FINISHED"
        assert processed["driving"] is False
        assert processed["orderId"] == "o1"
        assert processed["lastNodeId"] == "start"
        assert "noOrderToCancel" not in error_types(processed)
        assert robot.status is not None
        assert not robot.status.goal_active
