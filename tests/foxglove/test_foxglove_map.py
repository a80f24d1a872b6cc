"""The map of a robot on http:// on the Foxglove server: its PNG on /NAME/map when a viewer
subscribes and again when the map changes; nothing for a robot without the HTTP API."""

from __future__ import annotations

import asyncio
import json
from collections.abc import AsyncIterator

import pytest

pytest.importorskip("foxglove")

from galileo_async.foxglove import MAP_TOPICS, TOPICS, FoxgloveServer
from galileo_async.foxglove import map as map_module
from galileo_async.foxglove.schemas import MAP_INFO_SCHEMA_NAME
from galileo_async.robot import MapImage, Robot
from galileo_async.testing import SimulatedDevice, simulated_robot
from tests.support.foxglove_support import WAIT, connected

MAP = [(0.0, 0.0), (2.0, 0.0), (8.0, 8.0)]


@pytest.fixture
async def robot() -> AsyncIterator[tuple[Robot, SimulatedDevice]]:
    async with simulated_robot(clock="real", targets=MAP, link="http") as pair:
        yield pair


@pytest.fixture
async def server(robot: tuple[Robot, SimulatedDevice]) -> AsyncIterator[FoxgloveServer]:
    async with FoxgloveServer(port=0) as running:
        running.add_robot("alpha", robot[0])
        yield running


def maps(server: FoxgloveServer) -> map_module.MapChannels:
    """The map channels of robot alpha."""
    channels = server._robots["alpha"].map
    assert channels is not None
    return channels


async def the_map(robot: Robot) -> MapImage:
    assert robot.http is not None
    return await robot.http.map_image()


async def test_a_subscriber_gets_the_map_png_and_where_it_lies(
    server: FoxgloveServer, robot: tuple[Robot, SimulatedDevice]
) -> None:
    image = await the_map(robot[0])
    async with connected(server.url) as client:
        await client.until(lambda: len(client.channels) == len(TOPICS) + len(MAP_TOPICS))
        assert client.channels["/alpha/map"]["schemaName"] == "foxglove.CompressedImage"
        assert client.channels["/alpha/map_info"]["schemaName"] == MAP_INFO_SCHEMA_NAME
        await client.subscribe("/alpha/map", "/alpha/map_info")
        message = await client.next_message("/alpha/map")
        assert image.png in message  # the PNG as the robot gave it, format and frame beside it
        assert b"png" in message.replace(image.png, b"")
        assert b"map" in message.replace(image.png, b"")
        info = json.loads(await client.next_message("/alpha/map_info"))
        assert info == {
            "map": "sim",
            "frame_id": "map",
            "origin": dict(zip(("x", "y", "yaw"), image.origin, strict=True)),
            "width": image.width,
            "height": image.height,
            "resolution": image.resolution,
        }
        async with connected(server.url) as later:  # a later viewer gets it on subscribing
            await later.subscribe("/alpha/map")
            assert image.png in await later.next_message("/alpha/map")


async def test_a_switch_to_another_map_is_published_again(
    server: FoxgloveServer, robot: tuple[Robot, SimulatedDevice], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(map_module, "MAP_CHECK", 0.0)  # look at every tick
    async with connected(server.url) as client:
        await client.subscribe("/alpha/map_info", "/alpha/status")
        assert json.loads(await client.next_message("/alpha/map_info"))["map"] == "sim"
        assert robot[0].http is not None
        await robot[0].http.switch_map("floor2")
        info = json.loads(await client.next_message("/alpha/map_info"))
        assert info["map"] == "floor2"
        assert maps(server).current == "floor2"


async def test_a_robot_without_a_map_is_logged_and_read_again_on_the_next_subscription(
    server: FoxgloveServer,
    robot: tuple[Robot, SimulatedDevice],
    caplog: pytest.LogCaptureFixture,
) -> None:
    face = robot[1].http_face
    assert face is not None
    face.map_loaded = False
    async with connected(server.url) as client:
        await client.subscribe("/alpha/map", "/alpha/status")
        await client.until(lambda: maps(server).failed == 1)
        assert "alpha: no map image" in caplog.text
        assert "/alpha/map" not in client.messages
        face.map_loaded = True
        await client.subscribe("/alpha/map_info")
        assert json.loads(await client.next_message("/alpha/map_info"))["map"] == "sim"
        assert maps(server).published == 1


async def test_closing_the_server_cancels_a_map_read_under_way(
    robot: tuple[Robot, SimulatedDevice], monkeypatch: pytest.MonkeyPatch
) -> None:
    asked = asyncio.Event()

    async def never(self: object) -> MapImage:
        asked.set()
        await asyncio.Event().wait()
        raise AssertionError("unreachable")

    assert robot[0].http is not None
    monkeypatch.setattr(type(robot[0].http), "map_image", never)
    async with FoxgloveServer(port=0) as server:
        server.add_robot("alpha", robot[0])
        reading = maps(server)
        async with connected(server.url) as client:
            await client.subscribe("/alpha/map")
            await asyncio.wait_for(asked.wait(), WAIT)
            task = reading._task
            assert task is not None
    assert task.cancelled()


async def test_a_robot_without_the_http_api_has_no_map_channels() -> None:
    async with (
        simulated_robot(clock="real", targets=MAP) as (bot, _),
        FoxgloveServer(port=0) as server,
    ):
        server.add_robot("beta", bot)
        assert server._robots["beta"].map is None
        async with connected(server.url) as client:
            await client.until(lambda: len(client.channels) == len(TOPICS))
            assert "/beta/map" not in client.channels
