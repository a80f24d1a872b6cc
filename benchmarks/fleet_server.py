"""The fleet's robots, in their own process: ``python -m benchmarks.fleet_server N``.

N simulated robots, each on its own 127.0.0.1 port. ``--traffic burst`` (the default): one
shared Ticker, and once every listener is up all robots start in the same loop iteration,
so every robot's frame of a tick is written back to back and the reader finds them ready
together (reads batched). ``--traffic spread``: SPREAD_GROUPS Tickers, group ``g`` started
``g / SPREAD_GROUPS`` of a period after the first, so the fleet's frames are spread over the
period. Frame ``t`` of robot ``i`` is due at ``origin + offsets[i] + t / 30`` s on
CLOCK_MONOTONIC (the clock every process on the host shares). The first stdout line is
JSON: ports, that origin, the offsets and the frame period. Then it answers ``cpu`` on
stdin with its CPU seconds and device counters, and exits on EOF.
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


#: Tickers of ``--traffic spread``: robot ``i`` runs on ticker ``i % SPREAD_GROUPS``.
SPREAD_GROUPS = 100
PERIOD = 1.0 / 30


async def serve(count: int, patrol: bool, traffic: str = "burst") -> None:
    """Serve ``count`` robots until stdin closes (``traffic``: "burst" or "spread")."""
    loop = asyncio.get_running_loop()
    groups = SPREAD_GROUPS if traffic == "spread" else 1
    tickers = [Ticker(speed=1.0) for _ in range(groups)]
    devices = [SimDevice(SimConfig(seed=i, patrol_dwell=1.0), tickers[i % groups], lambda: None)
               for i in range(count)]  # fmt: skip
    offsets = [(i % groups) * PERIOD / groups for i in range(count)]
    servers = []
    for device in devices:
        if patrol:  # a busy fleet: every robot drives its patrol, so every frame changes
            device.model.submit(cmd.StartNavigation())
            device.model.submit(cmd.StartPatrol())

        def factory(device: SimDevice = device) -> asyncio.Protocol:
            return DeviceConnection(device)

        servers.append(await loop.create_server(factory, "127.0.0.1", 0, backlog=128))
    origin = loop.time()  # time.monotonic(); the first start() below sets the ticker's origin
    for device in devices[::groups]:
        device.start()
    for group in range(1, min(groups, count)):
        # Each group's first start() sets its ticker's origin: a call_at this late or later.
        loop.call_at(origin + offsets[group], _start, devices[group::groups])
    ports = [server.sockets[0].getsockname()[1] for server in servers]
    info = {"ports": ports, "origin": origin, "offsets": offsets, "period": PERIOD,
            "clock": "monotonic", "traffic": traffic, "package": PACKAGE}  # fmt: skip
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


def _start(devices: list[SimDevice]) -> None:
    for device in devices:
        device.start()


def main() -> None:
    """Parse arguments and serve."""
    parser = argparse.ArgumentParser(prog="python -m benchmarks.fleet_server")
    parser.add_argument("count", type=int)
    parser.add_argument("--idle", action="store_true", help="robots stand still")
    parser.add_argument("--traffic", choices=["burst", "spread"], default="burst")
    args = parser.parse_args()
    raise_fd_limit()
    asyncio.run(serve(args.count, patrol=not args.idle, traffic=args.traffic))


if __name__ == "__main__":
    main()
