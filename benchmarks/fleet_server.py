"""The fleet's robots, in their own process: ``python -m benchmarks.fleet_server N``.

N simulated robots on one shared Ticker, each on its own 127.0.0.1 port. Once every
listener is up, all robots start in the same loop iteration, so frame ``t`` of every robot
is due at ``origin + t / 30`` s on CLOCK_MONOTONIC (the clock every process on the host
shares). The first stdout line is JSON: ports, that origin and the frame period. Then it
answers ``cpu`` on stdin with its CPU seconds and device counters, and exits on EOF.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import sys
import time

import galileo_async
from galileo_async.protocol import commands as cmd
from galileo_async.sim import SimConfig
from galileo_async.sim.device import DeviceConnection, SimDevice, Ticker

from .common import raise_fd_limit

#: The package this server runs (benchmarks/compare.py checks which tree it came from).
PACKAGE = os.path.realpath(galileo_async.__file__)


async def serve(count: int, patrol: bool) -> None:
    """Serve ``count`` robots until stdin closes."""
    loop = asyncio.get_running_loop()
    ticker = Ticker(speed=1.0)
    devices = [SimDevice(SimConfig(seed=i, patrol_dwell=1.0), ticker, lambda: None)
               for i in range(count)]  # fmt: skip
    servers = []
    for device in devices:
        if patrol:  # a busy fleet: every robot drives its patrol, so every frame changes
            device.model.submit(cmd.StartNavigation())
            device.model.submit(cmd.StartPatrol())

        def factory(device: SimDevice = device) -> asyncio.Protocol:
            return DeviceConnection(device)

        servers.append(await loop.create_server(factory, "127.0.0.1", 0, backlog=128))
    origin = loop.time()  # time.monotonic(); the first start() below sets the ticker's origin
    for device in devices:
        device.start()
    ports = [server.sockets[0].getsockname()[1] for server in servers]
    info = {"ports": ports, "origin": origin, "period": 1.0 / 30, "clock": "monotonic",
            "package": PACKAGE}  # fmt: skip
    print(json.dumps(info), flush=True)
    reader = asyncio.StreamReader()
    await loop.connect_read_pipe(lambda: asyncio.StreamReaderProtocol(reader), sys.stdin)
    while line := await reader.readline():
        if line.strip() == b"cpu":
            sent = sum(device.stats.frames_sent for device in devices)
            connections = sum(len(device.connections) for device in devices)
            reply = {"cpu": time.process_time(), "frames_sent": sent, "connections": connections}
            print(json.dumps(reply), flush=True)
    for device in devices:
        device.stop()
    for server in servers:
        server.close()


def main() -> None:
    """Parse arguments and serve."""
    parser = argparse.ArgumentParser(prog="python -m benchmarks.fleet_server")
    parser.add_argument("count", type=int)
    parser.add_argument("--idle", action="store_true", help="robots stand still")
    args = parser.parse_args()
    raise_fd_limit()
    asyncio.run(serve(args.count, patrol=not args.idle))


if __name__ == "__main__":
    main()
