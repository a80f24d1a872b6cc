"""Robots as VDA 5050 2.0 vehicles on an MQTT broker, driven by a tiny master control.

    python examples/vda5050_vehicle.py [BROKER]   # default mqtt://127.0.0.1:1883

Two robots ($GALILEO_PORT or sim://) become vehicles ``acme/robot-0`` and ``acme/robot-1``
(topics ``uagv/v2/acme/robot-N/…``), each with its own MQTT session. The master part
sends each one a two-node order once its position is initialised, and prints where each
order ended. Without the
master part this is all a deployment needs: ``run_vehicles`` until Ctrl-C.
"""

from __future__ import annotations

import json
import os
import sys
from contextlib import AsyncExitStack

import aiomqtt
import anyio

import galileo_async as galileo
from galileo_async.vda5050 import Vehicle, VehicleConfig, parse_broker_url, run_vehicles

BROKER = sys.argv[1] if len(sys.argv) > 1 else "mqtt://127.0.0.1:1883"
URL = os.environ.get("GALILEO_PORT", "sim://")
GOALS = {"robot-0": (1.0, 1.0), "robot-1": (-1.0, 2.0)}


def order(serial: str, x: float, y: float) -> str:
    """A two-node order: from where the robot stands (0, 0) to (x, y)."""
    nodes = [
        {"nodeId": "here", "sequenceId": 0, "released": True, "actions": [],
         "nodePosition": {"x": 0.0, "y": 0.0, "mapId": "map", "allowedDeviationXY": 0.5}},
        {"nodeId": "goal", "sequenceId": 2, "released": True, "actions": [],
         "nodePosition": {"x": x, "y": y, "mapId": "map"}},
    ]  # fmt: skip
    edge = {"edgeId": "e1", "sequenceId": 1, "released": True, "startNodeId": "here",
            "endNodeId": "goal", "actions": []}  # fmt: skip
    return json.dumps({
        "headerId": 1, "timestamp": "2026-01-01T00:00:00.000Z", "version": "2.0.0",
        "manufacturer": "acme", "serialNumber": serial, "orderId": f"to-{x},{y}",
        "orderUpdateId": 0, "nodes": nodes, "edges": [edge],
    })  # fmt: skip


async def master() -> None:
    """Send each vehicle its order once it can drive; return when every order is done."""
    address = parse_broker_url(BROKER)
    async with aiomqtt.Client(address.host, address.port, identifier="example-master") as client:
        await client.subscribe("uagv/v2/acme/+/state")
        sent: set[str] = set()
        done: set[str] = set()
        async for message in client.messages:
            serial = str(message.topic).split("/")[3]
            state = json.loads(message.payload)  # type: ignore[arg-type]
            position = state.get("agvPosition") or {}
            if serial not in sent and position.get("positionInitialized"):
                sent.add(serial)  # navigation is open: the vehicle can take an order
                await client.publish(f"uagv/v2/acme/{serial}/order", order(serial, *GOALS[serial]))
            finished = state["lastNodeId"] == "goal" and not state["driving"]
            if serial in sent and serial not in done and finished:
                done.add(serial)
                print(f"{serial}: order {state['orderId']} done at "
                      f"({position['x']:.2f}, {position['y']:.2f})")  # fmt: skip
                if done == set(GOALS):
                    return


async def main() -> None:
    async with AsyncExitStack() as stack, anyio.create_task_group() as group:
        vehicles = []
        for serial in GOALS:
            robot = await stack.enter_async_context(galileo.connect(URL))
            config = VehicleConfig(
                broker=BROKER, manufacturer="acme", serial_number=serial, start_navigation=True
            )
            vehicles.append(Vehicle(robot, config))
        group.start_soon(run_vehicles, vehicles)
        with anyio.fail_after(120):
            await master()
        group.cancel_scope.cancel()  # the vehicles say OFFLINE and disconnect
    print("all vehicles offline")


if __name__ == "__main__":
    anyio.run(main)
