"""The Foxglove server against a plain WebSocket client decoding the ws-protocol by hand.

The robots are simulated on the real clock (the SDK's server runs on threads of its own);
every wait is bounded and waits for an event, never for a fixed time.
"""

from __future__ import annotations

import asyncio
import json
import socket
import time
from collections.abc import AsyncIterator
from typing import Any

import aiohttp
import pytest

from galileo_async.foxglove import (
    LEGACY_SUBPROTOCOL,
    SDK_SUBPROTOCOL,
    SERVICES,
    TOPICS,
    FoxgloveServer,
    serve_foxglove,
)
from galileo_async.foxglove import channels as channels_module
from galileo_async.models import TargetStatus
from galileo_async.protocol.commands import Goto
from galileo_async.robot import Robot
from galileo_async.schemas import STATUS_SCHEMA_NAME
from galileo_async.testing import SimulatedDevice, simulated_robot
from tests.support.cancel_ways import WAYS, stop_waiting
from tests.support.foxglove_support import WAIT, ServiceFailed, connected

MAP = [(0.0, 0.0), (2.0, 0.0), (8.0, 8.0)]  # target 2 is seconds away
TARGETS = [(i, x, y) for i, (x, y) in enumerate(MAP)]
SIM = {"speed": 2.0}  # a drive to (8, 8) takes about 6 s: a stop lands on the way


@pytest.fixture
async def robot() -> AsyncIterator[tuple[Robot, SimulatedDevice]]:
    async with simulated_robot(clock="real", targets=MAP, sim_options=SIM) as pair:
        yield pair


@pytest.fixture
async def server(robot: tuple[Robot, SimulatedDevice]) -> AsyncIterator[FoxgloveServer]:
    async with FoxgloveServer(port=0) as running:
        running.add_robot("alpha", robot[0], targets=TARGETS)
        yield running


async def test_every_channel_and_service_of_the_robot_is_advertised(
    server: FoxgloveServer,
) -> None:
    async with connected(server.url) as client:
        await client.until(lambda: len(client.channels) == 6 and len(client.services) == 7)
        assert client.ws.protocol == SDK_SUBPROTOCOL
        assert sorted(client.channels) == sorted(f"/alpha/{topic}" for topic in TOPICS)
        assert sorted(client.services) == sorted(f"/alpha/{name}" for name in SERVICES)
        status = client.channels["/alpha/status"]
        assert (status["encoding"], status["schemaName"]) == ("json", STATUS_SCHEMA_NAME)
        assert json.loads(status["schema"])["properties"]["target_status"]
        assert client.channels["/alpha/pose"]["schemaName"] == "foxglove.PoseInFrame"
        assert client.channels["/alpha/tf"]["schemaName"] == "foxglove.FrameTransform"
        assert client.channels["/alpha/scene"]["schemaName"] == "foxglove.SceneUpdate"
        assert client.channels["/alpha/events"]["schemaName"] == "foxglove.Log"
        goto = client.services["/alpha/goto"]
        assert json.loads(goto["request"]["schema"])["required"] == ["target"]
        assert "services" in client.server_info["capabilities"]


async def test_a_subscriber_gets_the_status_pose_transform_link_and_scene(
    server: FoxgloveServer, robot: tuple[Robot, SimulatedDevice]
) -> None:
    async with connected(server.url) as client:
        await client.subscribe(*(f"/alpha/{topic}" for topic in TOPICS if topic != "events"))
        status = json.loads(await client.next_message("/alpha/status"))
        assert status["nav_status"] == 1
        assert status["current_pose_x"] == pytest.approx(robot[1].pose.x, abs=0.5)
        assert b"map" in await client.next_message("/alpha/pose")
        assert b"alpha/base_link" in await client.next_message("/alpha/tf")
        link = json.loads(await client.next_message("/alpha/link"))
        assert link["state"] == "up"
        assert link["frames"] > 0
        assert link["lost_frames"] == 0
        scene = await client.next_message("/alpha/scene")
        assert b"alpha/target/2" in scene


async def test_goto_returns_on_acceptance_and_stop_stops_the_robot(
    server: FoxgloveServer, robot: tuple[Robot, SimulatedDevice]
) -> None:
    bot, device = robot
    async with connected(server.url) as client:
        await client.subscribe("/alpha/events")
        answer = await client.call("/alpha/goto", {"target": 2})
        assert answer == {"accepted": True, "target": 2, "arrived": False}
        assert bot.status is not None
        assert bot.status.target_num_id == 2  # accepted: the robot works on it
        await bot.wait_until(lambda s: (s.current_speed_x or 0) > 0, timeout=WAIT)
        assert b"GoalAccepted target_id=2" in await client.next_message("/alpha/events")
        assert await client.call("/alpha/stop", {}) == {"stopped": True}
        stopped = await bot.wait_until(lambda s: s.target_status != TargetStatus.WORKING, WAIT)
        where = device.pose
        assert stopped.target_status != TargetStatus.WORKING
        assert (where.x, where.y) != pytest.approx((8.0, 8.0), abs=0.2)


async def test_a_goto_still_waiting_when_stop_comes_is_never_sent(
    server: FoxgloveServer, robot: tuple[Robot, SimulatedDevice], monkeypatch: pytest.MonkeyPatch
) -> None:
    bot, device = robot
    device.busy(60.0)  # the goto waits out the busy robot
    await bot.wait_until(lambda s: bool(s.busy_status), timeout=WAIT)
    called = asyncio.Event()
    goto_of_robot = bot.goto

    async def goto(*args: Any, **options: Any) -> Any:
        called.set()
        return await goto_of_robot(*args, **options)

    monkeypatch.setattr(bot, "goto", goto)
    async with connected(server.url) as client:
        goto_call = asyncio.ensure_future(client.call("/alpha/goto", {"target": 1}))
        await asyncio.wait_for(called.wait(), WAIT)
        # A second client stops the robot while the first one's goto waits.
        async with connected(server.url) as other:
            assert await other.call("/alpha/stop", {}) == {"stopped": True}
        with pytest.raises(ServiceFailed, match="GoalCancelled"):
            await goto_call
    device.busy(0)
    await bot.wait_until(lambda s: not s.busy_status, timeout=WAIT)
    assert device.received(Goto) == []


@pytest.mark.parametrize(
    ("request_body", "message"),
    [
        (b"{not json", "goto: the request is not JSON"),
        (b"[3]", "goto: the request must be a JSON object"),
        (b"{}", "goto: missing 'target'"),
        (b'{"target": "three"}', "goto: target must be a target id 0..255, got 'three'"),
        (b'{"target": 3, "speed": 1}', "goto: unknown field(s) speed"),
        (b'{"target": 300}', "target must be a target id 0..255, got 300"),
    ],
)
async def test_a_bad_request_fails_with_a_message_that_says_why(
    server: FoxgloveServer, request_body: bytes, message: str
) -> None:
    async with connected(server.url) as client:
        with pytest.raises(ServiceFailed, match=message.replace("(", r"\(").replace(")", r"\)")):
            await client.call("/alpha/goto", request_body)


async def test_goto_point_needs_finite_numbers(server: FoxgloveServer) -> None:
    async with connected(server.url) as client:
        with pytest.raises(ServiceFailed, match="x must be a finite number of metres"):
            await client.call("/alpha/goto_point", {"x": "far", "y": 0})


async def test_an_unknown_target_is_the_robots_error(server: FoxgloveServer) -> None:
    async with connected(server.url) as client:
        with pytest.raises(ServiceFailed, match="GoalRejected: the robot rejected goal 7"):
            await client.call("/alpha/goto", {"target": 7})


async def test_the_older_subprotocol_name_is_served_on_the_same_port(
    server: FoxgloveServer,
) -> None:
    async with connected(server.url, LEGACY_SUBPROTOCOL) as client:
        assert client.ws.protocol == LEGACY_SUBPROTOCOL
        await client.subscribe("/alpha/status")
        assert json.loads(await client.next_message("/alpha/status"))["nav_status"] == 1
        assert await client.call("/alpha/cancel", {}) == {"cancelled": True}


async def test_a_client_offering_neither_name_is_refused(server: FoxgloveServer) -> None:
    async with aiohttp.ClientSession() as session:
        with pytest.raises(aiohttp.WSServerHandshakeError):
            await session.ws_connect(server.url, protocols=["something.else"])


async def test_nothing_is_encoded_for_nobody_and_statuses_are_throttled(
    robot: tuple[Robot, SimulatedDevice], monkeypatch: pytest.MonkeyPatch
) -> None:
    encoded: list[float] = []
    encode = channels_module.status_json

    def counting(status: object) -> bytes:
        encoded.append(time.monotonic())
        return encode(status)  # type: ignore[arg-type]

    monkeypatch.setattr(channels_module, "status_json", counting)
    bot = robot[0]
    async with FoxgloveServer(port=0, rate=4.0) as server:
        server.add_robot("alpha", bot)
        frames = bot.link.frames
        await bot.wait_until(lambda s: bot.link.frames >= frames + 30, timeout=WAIT)
        assert encoded == []  # 30 frames, no subscriber: nothing encoded
        async with connected(server.url) as client:
            await client.subscribe("/alpha/status")
            first = time.monotonic()
            for _ in range(6):
                await client.next_message("/alpha/status")
            last = time.monotonic()
        within = [at for at in encoded if first <= at <= last]
        # At most rate a second: one slot every 1/rate s (a slot taken late, by a frame
        # period at most, makes the next one come sooner).
        assert len(within) <= (last - first) * 4.0 + 2


async def test_closing_the_server_sends_nothing_and_frees_the_port(
    robot: tuple[Robot, SimulatedDevice],
) -> None:
    bot, device = robot
    async with FoxgloveServer(port=0) as server:
        server.add_robot("alpha", bot, targets=TARGETS)
        url = server.url
        async with connected(url) as client:
            assert (await client.call("/alpha/goto", {"target": 2}))["accepted"]
    sent = bot.link.commands_sent
    # The goal runs on to its end: closing the server cancelled nothing.
    await bot.wait_until(lambda s: s.target_status == TargetStatus.FREE, timeout=WAIT)
    assert (device.pose.x, device.pose.y) == pytest.approx((8.0, 8.0), abs=0.3)
    assert bot.link.commands_sent == sent
    async with aiohttp.ClientSession() as session:
        with pytest.raises(aiohttp.ClientConnectionError):
            await session.ws_connect(url, protocols=[SDK_SUBPROTOCOL])


@pytest.mark.parametrize("how", WAYS)
async def test_every_way_of_stopping_serve_foxglove_closes_it(
    how: str, robot: tuple[Robot, SimulatedDevice]
) -> None:
    bot = robot[0]
    started: asyncio.Future[FoxgloveServer] = asyncio.get_running_loop().create_future()
    urls: list[str] = []

    async def serve() -> None:
        async def note() -> None:
            urls.append((await started).url)

        watcher = asyncio.ensure_future(note())
        try:
            await serve_foxglove({"alpha": bot}, port=0, started=started)
        finally:
            watcher.cancel()

    sent = bot.link.commands_sent
    await stop_waiting(how, serve, after=2.0)
    assert len(urls) == 1
    assert bot.link.commands_sent == sent
    assert not bot.closed
    async with aiohttp.ClientSession() as session:
        with pytest.raises(aiohttp.ClientConnectionError):
            await session.ws_connect(urls[0], protocols=[SDK_SUBPROTOCOL])


async def test_a_cancelled_close_still_frees_the_port_and_stops_publishing() -> None:
    async with simulated_robot() as (bot, _):
        server = FoxgloveServer(port=0)
        await server.start()
        server.add_robot("alpha", bot)
        port = server.port
        calls = server._calls
        assert calls is not None
        answer_calls = calls.close

        async def slow_calls_close() -> None:  # close() is cancelled while it waits here
            await asyncio.sleep(1.0)
            await answer_calls()

        calls.close = slow_calls_close  # type: ignore[method-assign]
        closing = asyncio.ensure_future(server.close())
        await asyncio.sleep(0)
        closing.cancel()  # close() itself cancelled mid-way, then again
        await asyncio.sleep(0)
        closing.cancel()
        with pytest.raises(asyncio.CancelledError):
            await closing
        assert server.robots == ()
        with socket.socket() as probe:  # the public port itself, not only the SDK behind it
            assert probe.connect_ex(("127.0.0.1", port)) != 0
        await server.close()  # idempotent
