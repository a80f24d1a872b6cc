"""@foxglove/ws-protocol (npm, foxglove.websocket.v1) against the server: an independent client.

tests/peers/foxglove/client.cjs subscribes to a robot's status and pose, calls its goto
service (the simulated robot moves), then stop (the goal ends), then goto with a bad
request; each step is a JSON line. .ci/setup installs it (npm ci --prefix tests/peers/foxglove).
"""

from __future__ import annotations

import asyncio
import json
from collections.abc import AsyncIterator

import pytest

from galileo_async.foxglove import LEGACY_SUBPROTOCOL, FoxgloveServer
from galileo_async.testing import SimulatedDevice, simulated_robot
from tests.support.foxglove_support import PEER_DIR, WAIT, require_node_peer

MAP = [(0.0, 0.0), (3.0, 0.0), (6.0, 6.0)]


@pytest.fixture
async def served() -> AsyncIterator[tuple[FoxgloveServer, SimulatedDevice]]:
    async with (
        simulated_robot(clock="real", targets=MAP, sim_options={"speed": 1.0}) as (
            robot,
            device,
        ),
        FoxgloveServer(port=0) as server,
    ):
        server.add_robot("alpha", robot)
        yield server, device


async def test_the_ws_protocol_client_subscribes_moves_and_stops_the_robot(
    served: tuple[FoxgloveServer, SimulatedDevice],
) -> None:
    node = require_node_peer()
    server, device = served
    process = await asyncio.create_subprocess_exec(
        node, str(PEER_DIR / "client.cjs"), server.url, "alpha", "2",
        stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE,
    )  # fmt: skip
    try:
        out, err = await asyncio.wait_for(process.communicate(), 3 * WAIT)
    finally:
        if process.returncode is None:
            process.kill()
            await process.wait()
    lines = [json.loads(line) for line in out.decode().splitlines()]
    assert process.returncode == 0, (lines, err.decode())
    steps = {line["step"]: line for line in lines}
    assert steps["open"]["protocol"] == LEGACY_SUBPROTOCOL
    assert "services" in steps["serverInfo"]["capabilities"]
    assert "/alpha/goto" in steps["services"]["names"]
    topics = {line["topic"] for line in lines if line["step"] == "message"}
    assert topics == {"status", "pose"}
    answers = [line for line in lines if line["step"] == "response"]
    assert answers[0] == {
        "step": "response", "service": "goto",
        "answer": {"accepted": True, "target": 2, "arrived": False},
    }  # fmt: skip
    assert answers[1] == {"step": "response", "service": "stop", "answer": {"stopped": True}}
    assert steps["working"]["target"] == 2
    assert steps["ended"]["target_status"] != 1
    assert "target must be a target id 0..255, got 'three'" in steps["failure"]["message"]
    where = device.pose
    assert (where.x, where.y) != pytest.approx((6.0, 6.0), abs=0.3)  # stopped on the way
