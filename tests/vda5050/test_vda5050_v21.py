"""VDA 5050 2.1: every message validated against the 2.1.0 schemas, maps, errorHint, corridors."""

from __future__ import annotations

from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from typing import Any

import galileo_async as galileo
from galileo_async.robot import Robot
from galileo_async.vda5050 import Vehicle
from tests.support.vda5050_support import (
    Broker,
    Master,
    broker_fixture,  # noqa: F401 (the broker fixture)
    error_types,
    make_order,
    node,
)
from tests.vda5050.test_vda5050_vehicle import FAST_SIM, action_status, vehicle_on


@asynccontextmanager
async def vehicle_21(broker: Broker) -> AsyncIterator[tuple[Robot, Vehicle, Master]]:
    """A sim robot with navigation open, its 2.1 vehicle and a 2.1 master, all connected."""
    async with (
        Master.connected(broker, version="2.1.0") as master,
        galileo.connect(FAST_SIM) as robot,
        vehicle_on(broker, robot, vda_version="2.1") as vehicle,
    ):
        await robot.start_navigation()
        await master.wait_for("connection", lambda m: m["connectionState"] == "ONLINE")
        await master.wait_for("state", lambda s: s["operatingMode"] == "AUTOMATIC")
        yield robot, vehicle, master


def hinted(state: dict[str, Any], error_type: str) -> dict[str, Any]:
    """The newest error of ``error_type``, which carries an errorHint."""
    [*_, error] = [e for e in state["errors"] if e["errorType"] == error_type]
    assert error["errorHint"], error
    return error


async def test_a_2_1_vehicle_drives_an_order_and_reports_its_map(broker: Broker) -> None:
    async with vehicle_21(broker) as (_, _vehicle, master):
        factsheet = await master.wait_for("factsheet", lambda m: True)
        assert factsheet["version"] == "2.1.0"
        await master.order("o1", [node("start", 0.0, 0.0), node("a", 1.0, 0.0)])
        done = await master.next_state(lambda s: s["lastNodeId"] == "a" and not s["driving"])
        assert done["maps"] == [{"mapId": "map", "mapVersion": "current", "mapStatus": "ENABLED"}]
        assert master.received["visualization"]
        await master.instant(("f1", "factsheetRequest"))
        await master.next_state(lambda s: action_status(s, "f1") == "FINISHED")
        assert len(master.received["factsheet"]) >= 2


async def test_map_actions_fail_on_a_link_without_the_http_api(broker: Broker) -> None:
    async with vehicle_21(broker) as (_, _vehicle, master):
        await master.instant(("d1", "downloadMap"), ("e1", "enableMap"), ("x1", "deleteMap"))
        failed = await master.next_state(lambda s: action_status(s, "x1") == "FAILED")
        assert action_status(failed, "d1") == action_status(failed, "e1") == "FAILED"
        error = hinted(failed, "unsupportedAction")
        assert "maps" in error["errorDescription"]


async def test_a_corridor_is_refused_with_a_hint(broker: Broker) -> None:
    async with vehicle_21(broker) as (robot, _vehicle, master):
        order = make_order("c", [node("start", 0.0, 0.0), node("a", 1.0, 0.0)])
        order["edges"][0]["corridor"] = {"leftWidth": 0.5, "rightWidth": 0.5}
        await master.send("order", order)
        refused = await master.next_state(lambda s: "orderError" in error_types(s))
        error = hinted(refused, "orderError")
        assert {"referenceKey": "field", "referenceValue": "corridor"} in error["errorReferences"]
        assert refused["orderId"] == ""
        assert robot.status is not None
        assert not robot.status.goal_active
