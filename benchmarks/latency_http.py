"""Latency over ``http://``: status on the WebSocket, a command as a REST call.

The device end is an aiohttp server on 127.0.0.1 in the same process and loop, playing
the robot's HTTP API (REST) and its WebSocket: it sends a /galileo/status JSON message
on demand, frame ``k`` carrying ``targetNumID = k``, and timestamps each PUT
/system/speed it receives.

* **status → waiter**: t0 just before ``send_str``; t1 when ``await robot.wait_until(lambda
  s: s.target_num_id == k)`` returns. Baseline: a bare aiohttp WebSocket client that parses
  the JSON and resolves a future a task awaits.
* **command → request**: t0 just before ``await robot.send(Velocity(0.1, 0))``; t1 when the
  device's handler runs. Baseline: ``session.put(…/system/speed, json=…)`` on one session.
"""

from __future__ import annotations

import asyncio
import json
import time

import aiohttp
from aiohttp import web

import galileo_async
from galileo_async import GalileoStatus
from galileo_async.protocol import Velocity

from .latency_loops import Arrivals, bare_status, driver_status, timed_commands

__all__ = ["http_command_latency", "http_status_latency"]

_FIELDS = {
    "navStatus": 1, "visualStatus": 1, "mapStatus": 0, "gcStatus": 0, "gbaStatus": 0,
    "chargeStatus": 0, "loopStatus": 0, "power": 24.0, "targetNumID": 0, "targetStatus": 0,
    "targetDistance": 0.0, "angleGoalStatus": 1, "controlSpeedX": 0.0,
    "controlSpeedTheta": 0.0, "currentSpeedX": 0.0, "currentSpeedTheta": 0.0,
    "currentPosX": 0.0, "currentPosY": 0.0, "currentAngle": 0.0, "busyStatus": 0,
}  # fmt: skip


def _message(k: int) -> str:
    return json.dumps({"header": {"seq": k}, **_FIELDS, "targetNumID": k})


class _Device:
    """REST and WebSocket on one port; ``sockets`` are the open status streams."""

    def __init__(self) -> None:
        self.sockets: list[web.WebSocketResponse] = []
        self.connected = asyncio.Event()
        self.arrivals = Arrivals()
        self.runner: web.AppRunner | None = None
        self.port = 0

    async def start(self) -> None:
        app = web.Application()
        app.add_routes(
            [web.get("/galileo/status", self._ws), web.put("/api/v1/system/speed", self._speed)]
        )
        self.runner = web.AppRunner(app, handle_signals=False, access_log=None)
        await self.runner.setup()
        site = web.TCPSite(self.runner, "127.0.0.1", 0)
        await site.start()
        self.port = site._server.sockets[0].getsockname()[1]  # type: ignore[union-attr]

    async def _ws(self, request: web.Request) -> web.WebSocketResponse:
        ws = web.WebSocketResponse()
        await ws.prepare(request)
        self.sockets.append(ws)
        await ws.send_str(_message(1))  # the host's connect waits for a status
        self.connected.set()
        async for _ in ws:
            pass
        self.sockets.remove(ws)
        return ws

    async def _speed(self, request: web.Request) -> web.Response:
        self.arrivals(time.perf_counter())
        await request.read()
        return web.json_response({"result": True})

    async def send(self, k: int) -> None:
        await self.sockets[-1].send_str(_message(k))

    async def stop(self) -> None:
        for ws in list(self.sockets):
            await ws.close()
        if self.runner is not None:
            await self.runner.cleanup()


def _url(port: int) -> str:
    return f"http://127.0.0.1:{port}?ws_port={port}"


async def http_status_latency(samples: int) -> tuple[list[float], list[float], list[float]]:
    """Device send_str → waiter woken, driver and bare, and the driver's status ages, seconds."""
    device = _Device()
    await device.start()
    try:
        robot = await galileo_async.connect(_url(device.port), stale_timeout=None)
        try:
            driver, ages = await driver_status(robot, device.send, _target, samples)
        finally:
            await robot.close()
        async with (
            aiohttp.ClientSession() as session,
            session.ws_connect(f"ws://127.0.0.1:{device.port}/galileo/status") as ws,
        ):
            await ws.receive()

            async def wait(k: int) -> None:
                while json.loads((await ws.receive()).data)["targetNumID"] != k:
                    pass

            bare = await bare_status(device.send, wait, samples)
    finally:
        await device.stop()
    return driver, bare, ages


def _target(status: GalileoStatus) -> int | None:
    return status.target_num_id


async def http_command_latency(samples: int) -> tuple[list[float], list[float]]:
    """robot.send(Velocity) call → PUT at the device, driver and bare, in seconds."""
    device = _Device()
    await device.start()
    try:
        robot = await galileo_async.connect(_url(device.port), stale_timeout=None)
        try:
            driver = await timed_commands(
                lambda: robot.send(Velocity(0.1, 0.0)), device.arrivals, samples
            )
        finally:
            await robot.close()
        url = f"http://127.0.0.1:{device.port}/api/v1/system/speed"
        body = {"speed_x": 0.1, "speed_y": 0.0, "speed_angle": 0.0}
        async with aiohttp.ClientSession() as session:

            async def put() -> None:
                async with session.put(url, json=body) as response:
                    await response.read()

            bare = await timed_commands(put, device.arrivals, samples)
    finally:
        await device.stop()
    return driver, bare
