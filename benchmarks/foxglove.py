"""Foxglove: N robots behind one FoxgloveServer, with no viewer and with one subscribed to all.

The robots are simulated robots patrolling in a ``benchmarks.fleet_server`` process (traffic
spread over the frame period, 30 frames/s each), connected here over ``socket://``. Three
windows on the same robots, in one run:

* **no server** (the baseline): the robots only;
* **server, no client**: every robot added to one server (6 channels, 7 services each);
  nothing is subscribed, so nothing is encoded;
* **server, one client**: a client in its own process (aiohttp, foxglove.sdk.v1) subscribed
  to every channel of every robot, through the relay; it counts what it receives.

CPU: this process's CPU time (every thread: the SDK's server runs on threads of its own)
over the window / wall time, per robot and in cores; the client's process is measured from
/proc beside it. RSS per robot: this process's resident memory with the server and every
robot added, less the same before the server started, / N.
"""

from __future__ import annotations

import asyncio
import json
import struct
import sys
import time
from typing import Any

import aiohttp

from galileo_async.foxglove import DEFAULT_RATE, FoxgloveServer
from galileo_async.robot import Robot

from .common import Row, raise_fd_limit
from .fleet import _connect, _Server
from .vda5050 import _rss, process_cpu

__all__ = ["client", "measure", "run"]

#: Seconds the client has to connect and subscribe to every channel.
CLIENT_READY = 120.0


async def _window(seconds: float) -> tuple[float, float]:
    """(CPU seconds, wall seconds) of this process over ``seconds``."""
    cpu, wall = time.process_time(), time.perf_counter()
    await asyncio.sleep(seconds)
    return time.process_time() - cpu, time.perf_counter() - wall


async def measure(
    robots: list[Robot], seconds: float, rate: float = DEFAULT_RATE
) -> dict[str, Any]:
    """The three windows on ``robots``: CPU in cores, RSS, the client's counts."""
    bare_cpu, bare_wall = await _window(seconds)
    before = _rss()
    async with FoxgloveServer(port=0, rate=rate) as server:
        for index, robot in enumerate(robots):
            server.add_robot(f"r{index}", robot)
        rss = (_rss() - before) / len(robots)
        idle_cpu, idle_wall = await _window(seconds)
        viewer = await asyncio.create_subprocess_exec(
            sys.executable, "-m", "benchmarks.foxglove", server.url, str(seconds),
            str(6 * len(robots)),
            stdout=asyncio.subprocess.PIPE,
        )  # fmt: skip
        assert viewer.stdout is not None
        try:
            ready = await asyncio.wait_for(viewer.stdout.readline(), CLIENT_READY)
            assert json.loads(ready)["subscribed"] == 6 * len(robots), ready
            viewer_cpu = process_cpu(viewer.pid)
            busy_cpu, busy_wall = await _window(seconds)
            viewer_cpu = process_cpu(viewer.pid) - viewer_cpu
            counts = json.loads(await asyncio.wait_for(viewer.stdout.readline(), CLIENT_READY))
        finally:
            if viewer.returncode is None:
                viewer.kill()
            await viewer.wait()
    return {
        "bare_cores": bare_cpu / bare_wall,
        "idle_cores": idle_cpu / idle_wall,
        "busy_cores": busy_cpu / busy_wall,
        "client_cores": viewer_cpu / busy_wall,
        "rss_per_robot": rss,
        "messages_per_second": counts["messages"] / counts["seconds"],
        "bytes_per_second": counts["bytes"] / counts["seconds"],
    }


async def _measure_on(server: _Server, seconds: float, rate: float) -> dict[str, Any]:
    robots = await _connect(server)
    try:
        await asyncio.sleep(1.0)  # every robot's first frames in
        return await measure(robots, seconds, rate)
    finally:
        await asyncio.gather(*(robot.close() for robot in robots), return_exceptions=True)


def run(
    *, quick: bool = False, robots: int | None = None, seconds: float | None = None,
    rate: float = DEFAULT_RATE,
) -> list[Row]:  # fmt: skip
    """The three windows at N robots (default 1000; --quick 50), ``seconds`` each (10; 3);
    ``rate``: the server's pose and status messages a second per robot."""
    count = robots or (50 if quick else 1000)
    seconds = seconds or (3.0 if quick else 10.0)
    raise_fd_limit()
    server = _Server(count, traffic="spread")
    try:
        figures = asyncio.run(_measure_on(server, seconds, rate))
    finally:
        server.close()
    extra = {
        "robots": count, "rate": rate, "robots_from": "fleet_server, socket://",
        "messages_per_second": figures["messages_per_second"],
        "bytes_per_second": figures["bytes_per_second"],
    }  # fmt: skip
    bare = figures["bare_cores"]
    per = 100 / count
    return [
        Row("foxglove", f"CPU per robot, server, no client ({count} robots, rate {rate:g})",
            figures["idle_cores"] * per, "% core", bare * per, "no server", extra=extra),
        Row("foxglove", "CPU per robot, server, one client subscribed to everything",
            figures["busy_cores"] * per, "% core", bare * per, "no server", extra=extra),
        Row("foxglove", "CPU of the server, one client (robots not counted)",
            figures["busy_cores"] - bare, "cores", figures["idle_cores"] - bare, "no client",
            extra=extra),
        Row("foxglove", "CPU of the client process", figures["client_cores"], "cores",
            extra=extra),
        Row("foxglove", "RSS per robot (server and channels)", figures["rss_per_robot"] / 1024,
            "KiB", extra=extra),
        Row("foxglove", "messages to the client", figures["messages_per_second"], "msg/s",
            extra=extra),
    ]  # fmt: skip


async def client(url: str, seconds: float, expected: int) -> None:
    """The viewer: subscribe to ``expected`` channels, print a line, count a window, then counts."""
    async with (
        aiohttp.ClientSession() as session,
        session.ws_connect(url, protocols=["foxglove.sdk.v1"], max_msg_size=0) as ws,
    ):
        channels: list[int] = []
        while len(channels) < expected:
            message = await ws.receive()
            if message.type == aiohttp.WSMsgType.TEXT:
                data = json.loads(message.data)
                if data["op"] == "advertise":
                    channels += [channel["id"] for channel in data["channels"]]
        subscriptions = [{"id": i, "channelId": c} for i, c in enumerate(channels)]
        await ws.send_str(json.dumps({"op": "subscribe", "subscriptions": subscriptions}))
        print(json.dumps({"subscribed": len(channels)}), flush=True)
        counted = {"messages": 0, "bytes": 0}
        started = time.perf_counter()
        while time.perf_counter() - started < seconds:
            message = await ws.receive()
            if message.type == aiohttp.WSMsgType.BINARY and message.data[0] == 1:
                struct.unpack_from("<IQ", message.data, 1)
                counted["messages"] += 1
                counted["bytes"] += len(message.data)
        seconds = time.perf_counter() - started
        print(json.dumps({**counted, "seconds": seconds}), flush=True)


if __name__ == "__main__":
    asyncio.run(client(sys.argv[1], float(sys.argv[2]), int(sys.argv[3])))
