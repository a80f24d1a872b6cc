"""VDA 5050 edge maxSpeed: honoured through the navigation speed over http://, else refused."""

from __future__ import annotations

import contextlib
from collections.abc import AsyncIterator
from typing import Any

import pytest

import galileo_async as galileo
from galileo_async.robot import Robot
from galileo_async.sim import Simulator
from tests.links.test_http_link import http_of
from tests.support.sim_integration import speeds_of
from tests.support.vda5050_support import (
    Broker,
    Master,
    broker_fixture,  # noqa: F401 (the broker fixture)
    error_types,
    make_order,
    node,
)
from tests.vda5050.test_vda5050_vehicle import action_status, vehicle_on

pytestmark = pytest.mark.timeout(60)

TOP = 0.8  # the simulator's max_speed and so its initial navigation_speed


@contextlib.asynccontextmanager
async def http_vehicle(
    broker: Broker, link: str = "http"
) -> AsyncIterator[tuple[Robot, Any, Master]]:
    """A simulated robot on http:// (or socket://), navigating, its vehicle and a master."""
    async with Simulator(speed=40.0, targets=((1.5, 0.0), (30.0, 0.0))) as sim:
        if link == "http":
            face: Any = await sim.serve_http()
            url = f"http://127.0.0.1:{face.address[1]}?ws_port={face.ws_address[1]}"
        else:
            face = await sim.serve_tcp()
            url = f"socket://127.0.0.1:{face.sockets[0].getsockname()[1]}"
        async with (
            Master.connected(broker) as master,
            galileo.connect(url, map_targets=2) as robot,
            vehicle_on(broker, robot),
        ):
            await robot.wait_until(lambda s: True, timeout=10.0)
            await robot.start_navigation(timeout=10.0)
            await master.wait_for("connection", lambda m: m["connectionState"] == "ONLINE")
            await master.wait_for("state", lambda s: s["operatingMode"] == "AUTOMATIC")
            yield robot, face, master


def slow_order(order_id: str, x: float) -> dict[str, Any]:
    order = make_order(order_id, [node("start", 0.0, 0.0), node("a", x, 0.0)])
    order["edges"][0]["maxSpeed"] = 0.1
    return order


async def test_edge_max_speed_is_driven_at_over_http_then_restored(broker: Broker) -> None:
    async with http_vehicle(broker) as (robot, face, master):
        factsheet = await master.wait_for("factsheet", lambda m: True)
        honoured = [p["parameter"] for p in factsheet["protocolFeatures"]["optionalParameters"]]
        assert "order.edges.maxSpeed" in honoured
        async with speeds_of(robot) as speeds:
            await master.send("order", slow_order("slow", 0.6))
            done = await master.next_state(lambda s: s["lastNodeId"] == "a")
        assert done["orderId"] == "slow"
        assert "orderError" not in error_types(done)
        assert max(speeds) > 0.05  # it drove
        assert max(speeds) <= 0.1 + 1e-6
        assert face.device.model.navigation_speed == pytest.approx(TOP)
        assert await http_of(robot).navigation_speed() == pytest.approx(TOP)


async def test_edge_max_speed_restored_after_a_cancel(broker: Broker) -> None:
    async with http_vehicle(broker) as (robot, face, master):
        await master.send("order", slow_order("slow", 30.0))
        await master.next_state(lambda s: s["driving"])
        assert face.device.model.navigation_speed == pytest.approx(0.1)
        await master.instant(("c1", "cancelOrder"))
        await master.next_state(lambda s: action_status(s, "c1") == "FINISHED")
        assert face.device.model.navigation_speed == pytest.approx(TOP)
        assert robot.status is not None
        assert not robot.status.goal_active


async def test_edge_max_speed_still_refused_over_socket(broker: Broker) -> None:
    async with http_vehicle(broker, "socket") as (robot, _, master):
        factsheet = await master.wait_for("factsheet", lambda m: True)
        honoured = [p["parameter"] for p in factsheet["protocolFeatures"]["optionalParameters"]]
        assert "order.edges.maxSpeed" not in honoured
        await master.send("order", slow_order("slow", 0.6))
        refused = await master.next_state(lambda s: "orderError" in error_types(s))
        assert refused["orderId"] == ""
        assert robot.status is not None
        assert not robot.status.goal_active
