"""Serve a robot's Prometheus metrics while it works; print what a scrape shows.

python examples/metrics.py [URL] [PORT]   # default: $GALILEO_PORT, else sim://; port 9464

Needs the extra metrics (pip install 'galileo-async[metrics]'). While it runs, Prometheus
can scrape http://127.0.0.1:PORT/metrics; here the program scrapes itself once at the end.
"""

from __future__ import annotations

import asyncio
import os
import sys

import aiohttp

import galileo_async as galileo
from galileo_async.metrics import Metrics, serve_metrics

URL = sys.argv[1] if len(sys.argv) > 1 else os.environ.get("GALILEO_PORT", "sim://")
PORT = int(sys.argv[2]) if len(sys.argv) > 2 else 9464
SHOWN = ("galileo_odometer_meters_total", "galileo_goals_ended_total", "galileo_battery_")


async def main() -> int:
    metrics = Metrics()
    async with (
        galileo.connect(URL) as robot,
        serve_metrics(metrics, "127.0.0.1", PORT) as server,
    ):
        metrics.add_robot(robot, name="robot1")
        print(f"serving {server.url}")
        await robot.start_navigation(timeout=60)
        for target in (1, 2):
            await robot.goto(target, timeout=120)
        async with aiohttp.ClientSession() as session, session.get(server.url) as answer:
            text = await answer.text()
        metrics.close()
    for line in text.splitlines():
        if line.startswith(SHOWN):
            print(line)
    return 0


if __name__ == "__main__":
    sys.exit(asyncio.run(main()))
