"""A master control drives the VDA 5050 vehicle over a real Mosquitto against sim:// robots."""

from __future__ import annotations

import math
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from pathlib import Path
from typing import Any

import anyio
import pytest
from vda5050_support import Broker, Master, error_types, make_order, node

import galileo_async as galileo
from galileo_async.robot import Robot
from galileo_async.vda5050 import Vehicle, VehicleConfig

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


@pytest.fixture
async def broker(tmp_path: Path) -> AsyncIterator[Broker]:
    async with Broker.running(tmp_path) as running:
        yield running


@asynccontextmanager
async def setup(
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
    async with setup(broker) as (_, _vehicle, master):
        factsheet = await master.wait_for("factsheet", lambda m: True)
        assert "cancelOrder" in [a["actionType"] for a in factsheet["protocolFeatures"]["agvActions"]]
        await master.order("o1", [node("start", 0.0, 0.0), node("a", 1.0, 0.0), node("b", 1.0, 1.0)])
        first = await master.next_state(lambda s: s["orderId"] == "o1")
        assert first["lastNodeId"] == "start"
        assert [n["nodeId"] for n in first["nodeStates"]] == ["a", "b"]
        halfway = await master.next_state(lambda s: s["lastNodeId"] == "a")
        assert [n["nodeId"] for n in halfway["nodeStates"]] == ["b"]
        assert halfway["lastNodeSequenceId"] == 2
        done = await master.next_state(lambda s: s["lastNodeId"] == "b" and not s["driving"])
        assert done["nodeStates"] == [] and done["edgeStates"] == []
        assert near(done, 1.0, 1.0)
        assert done["errors"] == []
        assert master.received["visualization"]
