"""robot.http.map_image() and map_png() against the simulator's HTTP face; bad answers."""

from __future__ import annotations

from typing import Any

import pytest
from aiohttp import web

from galileo_async import HttpError, OperationFailed
from galileo_async.robot import MapImage
from galileo_async.sim.map_image import FREE, TARGET, WALL
from tests.links.test_http_link import TARGETS, http_of, robot_on_http
from tests.support.png import grey_pixels

pytestmark = pytest.mark.timeout(60)


def pixel(image: MapImage, x: float, y: float) -> int:
    """The grey level at map point (x, y) m: rows from the top, origin the lower left pixel."""
    rows = grey_pixels(image.png)
    col = round((x - image.origin[0]) / image.resolution)
    row = image.height - 1 - round((y - image.origin[1]) / image.resolution)
    return rows[row][col]


async def test_map_image_is_the_current_maps_png_placed_on_the_map() -> None:
    async with robot_on_http() as (sim, robot, face):
        image = await http_of(robot).map_image()
        assert image.resolution == pytest.approx(0.05)
        rows = grey_pixels(image.png)
        assert (len(rows[0]), len(rows)) == (image.width, image.height)
        assert image.origin[2] == 0.0
        for x, y in TARGETS:  # each target is a dot where its coordinates say
            assert pixel(image, x, y) == TARGET
        dock_x, dock_y = sim.config.dock
        assert pixel(image, dock_x, dock_y) == TARGET
        assert pixel(image, 15.0, 0.0) == FREE
        assert rows[0][0] == rows[-1][-1] == WALL
        assert "png" not in repr(image).split("(", 1)[1]  # the bytes are left out of repr
        assert await http_of(robot).map_png("floor2") == image.png
        with pytest.raises(HttpError) as info:
            await http_of(robot).map_png("nowhere")
        assert (info.value.status, info.value.endpoint) == (404, "/navigation/map_png")
        assert face.requests > 0


async def test_no_map_loaded_is_operation_failed() -> None:
    async with robot_on_http() as (_, robot, face):
        face.map_loaded = False
        with pytest.raises(OperationFailed, match="no map loaded"):
            await http_of(robot).map_image()


async def test_an_answer_that_is_no_png_or_no_map_is_operation_failed() -> None:
    async with robot_on_http() as (_, robot, face):

        def page(found: bool) -> web.Response:
            return web.Response(text="<html>busy</html>", content_type="text/html")

        face._map_png = page  # type: ignore[method-assign]
        with pytest.raises(OperationFailed, match="answered no PNG"):
            await http_of(robot).map_image()
        with pytest.raises(OperationFailed, match="answered no PNG"):
            await http_of(robot).map_png("sim")

        def odd(**params: Any) -> Any:
            return lambda: {"status": "OK", "map_params": params, "map_image": "/x"}

        face._map_image = odd(origin="left", width=3, height=3, resolution=0.05)  # type: ignore[method-assign]
        with pytest.raises(OperationFailed, match="map_params not understood"):
            await http_of(robot).map_image()
        face._map_image = lambda: {"status": "OK"}  # type: ignore[method-assign]
        with pytest.raises(OperationFailed, match="no map loaded"):
            await http_of(robot).map_image()


async def test_a_png_sent_as_octet_stream_is_bytes_too() -> None:
    async with robot_on_http() as (_, robot, face):
        png = (await http_of(robot).map_image()).png

        def stream(found: bool) -> web.Response:
            return web.Response(body=png, content_type="application/octet-stream")

        face._map_png = stream  # type: ignore[method-assign]
        assert await http_of(robot).map_png("sim") == png
        assert (await http_of(robot).map_image()).png == png


async def test_an_image_path_outside_the_api_falls_back_to_the_documented_one() -> None:
    async with robot_on_http() as (_, robot, face):
        image = await http_of(robot).map_image()
        answer = {"status": "OK", "map_params": face._sim_map().params(), "map_image": "http://x/"}
        face._map_image = lambda: answer  # type: ignore[method-assign]
        assert await http_of(robot).map_image() == image


async def test_a_charge_pose_answer_without_a_pose_is_operation_failed(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    async with robot_on_http() as (sim, robot, _face):
        http = http_of(robot)
        assert (await http.charge_pose()).x == sim.model.dock[0]

        async def no_pose(*_args: Any) -> Any:
            return {"status": "no charger on this map"}

        monkeypatch.setattr(type(http), "_call", no_pose)
        with pytest.raises(OperationFailed, match="charge_pose\\(\\): no pose in"):
            await http.charge_pose()
