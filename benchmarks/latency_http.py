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
from typing import Any

import aiohttp
from aiohttp import web

import galileo_async
from galileo_async.protocol import Velocity

__all__ = ["http_command_latency", "http_status_latency"]

COMMAND_GAP = 0.012  # above the 10 ms pacing
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
        self.arrivals: list[float] = []
        self.arrived = asyncio.Event()
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
        self.arrivals.append(time.perf_counter())
        self.arrived.set()
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


async def http_status_latency(samples: int) -> tuple[list[float], list[float]]:
    """Device send_str → waiter woken, driver and bare, in seconds."""
    device = _Device()
    await device.start()
    perf = time.perf_counter
    driver: list[float] = []
    bare: list[float] = []
    try:
        robot = await galileo_async.connect(_url(device.port), stale_timeout=None)
        try:
            for k in range(2, samples + 2):

                def wanted(status: Any, k: int = k) -> bool:
                    return bool(status.target_num_id == k)

                waiter = asyncio.create_task(robot.wait_until(wanted, timeout=5))
                await asyncio.sleep(0)
                t0 = perf()
                await device.send(k)
                await waiter
                driver.append(perf() - t0)
        finally:
            await robot.close()
        async with (
            aiohttp.ClientSession() as session,
            session.ws_connect(f"ws://127.0.0.1:{device.port}/galileo/status") as ws,
        ):
            await ws.receive()
            for k in range(2, samples + 2):

                async def wait(k: int = k) -> None:
                    while json.loads((await ws.receive()).data)["targetNumID"] != k:
                        pass

                bare_waiter = asyncio.create_task(wait())
                await asyncio.sleep(0)
                t0 = perf()
                await device.send(k)
                await bare_waiter
                bare.append(perf() - t0)
    finally:
        await device.stop()
    return driver, bare


async def http_command_latency(samples: int) -> tuple[list[float], list[float]]:
    """robot.send(Velocity) call → PUT at the device, driver and bare, in seconds."""
    device = _Device()
    await device.start()
    perf = time.perf_counter
    driver: list[float] = []
    bare: list[float] = []

    async def arrival(before: int) -> float:
        while len(device.arrivals) == before:
            device.arrived.clear()
            await device.arrived.wait()
        return device.arrivals[before]

    try:
        robot = await galileo_async.connect(_url(device.port), stale_timeout=None)
        try:
            for _ in range(samples):
                await asyncio.sleep(COMMAND_GAP)
                before = len(device.arrivals)
                t0 = perf()
                await robot.send(Velocity(0.1, 0.0))
                driver.append(await asyncio.wait_for(arrival(before), 5) - t0)
        finally:
            await robot.close()
        url = f"http://127.0.0.1:{device.port}/api/v1/system/speed"
        body = {"speed_x": 0.1, "speed_y": 0.0, "speed_angle": 0.0}
        async with aiohttp.ClientSession() as session:
            for _ in range(samples):
                await asyncio.sleep(COMMAND_GAP)
                before = len(device.arrivals)
                t0 = perf()
                async with session.put(url, json=body) as response:
                    await response.read()
                bare.append(device.arrivals[before] - t0)
    finally:
        await device.stop()
    return driver, bare
