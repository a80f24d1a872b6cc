"""Maps, battery and a goal by pose through the robot's HTTP API (needs the extra [http]).

python examples/http_maps.py [URL]   # http://robot:3546; default: $GALILEO_PORT, else sim://
A sim:// URL starts the simulator with its HTTP face on loopback and connects to that.
"""

from __future__ import annotations

import asyncio
import contextlib
import os
import sys
from collections.abc import AsyncIterator

import galileo_async as galileo
from galileo_async.sim import Simulator

URL = sys.argv[1] if len(sys.argv) > 1 else os.environ.get("GALILEO_PORT", "sim://")


@contextlib.asynccontextmanager
async def http_url(url: str) -> AsyncIterator[str]:
    """``url`` itself, or for sim:// the http:// URL of a simulator started for the example."""
    if not url.startswith("sim://"):
        yield url
        return
    async with Simulator.from_url(url) as sim:
        face = await sim.serve_http()
        yield f"http://127.0.0.1:{face.address[1]}?ws_port={face.ws_address[1]}"


async def main() -> int:
    async with http_url(URL) as url:
        try:
            async with galileo.connect(url) as robot:
                http = robot.http  # None on a link without the HTTP API
                if http is None:
                    print(f"{url} is no http:// or https:// link", file=sys.stderr)
                    return 2
                info = await http.info()
                print(f"firmware {info.version} ({info.code_name})")
                print(f"battery: {await http.battery_percent()} %")
                print(f"maps: {', '.join(await http.maps())}")
                current = await http.current_map()
                print(f"current map: {current.map}, path {current.path}")
                for index, point in enumerate(await http.targets()):
                    print(f"target {index}: ({point.x:.2f}, {point.y:.2f})")
                switched = await http.switch_map(current.map)  # no navigation restart
                print(f"switched to {switched.map}, path {switched.path}")
                await robot.start_navigation(timeout=60)
                try:
                    result = await http.goto_pose(1.0, 0.5, 0.0, timeout=120)
                except galileo.GoalError as exc:
                    print(f"goal by pose failed: {type(exc).__name__}: {exc}")
                    return 1
                print(f"arrived at (1.0, 0.5) after {result.elapsed:.1f} s")
        except galileo.GalileoConnectionError as exc:
            print(f"link problem: {exc}", file=sys.stderr)
            return 1
    return 0


if __name__ == "__main__":
    sys.exit(asyncio.run(main()))
