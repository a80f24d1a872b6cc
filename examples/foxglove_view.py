"""Two simulated robots in a Foxglove live view, each touring its map's targets.

    python examples/foxglove_view.py [SECONDS [PORT]]   # default: until Ctrl-C, port 8765

Needs the extra [foxglove]. Open the printed ws:// URL in Foxglove or Lichtblick; the
layout docs/foxglove-layout.json shows a robot named "robot": rename its topics' prefix
to /alpha or /beta. The Service Call panel's stop (/alpha/stop) stops a robot; its tour
then ends with the goal's GoalCancelled.
"""

from __future__ import annotations

import os
import sys

import anyio

import galileo_async as galileo
from galileo_async.errors import GoalError
from galileo_async.foxglove import FoxgloveServer
from galileo_async.robot import Robot
from galileo_async.sim import parse_sim_url

URL = os.environ.get("GALILEO_PORT", "sim://")
SECONDS = float(sys.argv[1]) if len(sys.argv) > 1 else None
PORT = int(sys.argv[2]) if len(sys.argv) > 2 else 8765


async def tour(name: str, robot: Robot, targets: list[int]) -> None:
    """Visit ``targets`` over and over until a goal fails (a stop from Foxglove, say)."""
    await robot.start_navigation(timeout=60)
    try:
        while True:
            for target_id in targets:
                result = await robot.goto(target_id, timeout=120)
                print(f"{name}: arrived at {result.target_id}", flush=True)
    except GoalError as exc:
        print(f"{name}: tour ended: {exc}", flush=True)


async def main() -> None:
    points = parse_sim_url(URL).targets
    known = [(target_id, x, y) for target_id, (x, y) in enumerate(points)]
    async with (
        galileo.connect(URL) as alpha,
        galileo.connect(URL) as beta,
        FoxgloveServer(port=PORT) as server,
    ):
        server.add_robot("alpha", alpha, targets=known)
        server.add_robot("beta", beta, targets=known)
        print(f"open {server.url} in Foxglove or Lichtblick", flush=True)
        ids = list(range(len(points)))
        with anyio.move_on_after(SECONDS):  # None: until Ctrl-C
            async with anyio.create_task_group() as group:
                group.start_soon(tour, "alpha", alpha, ids[1:] + ids[:1])
                group.start_soon(tour, "beta", beta, ids[::-1])


if __name__ == "__main__":
    anyio.run(main)
