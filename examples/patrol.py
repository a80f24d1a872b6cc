"""Patrol every target, print each arrival from the event stream, stop after a few.

python examples/patrol.py [URL]    # default: $GALILEO_PORT, else sim://
"""

from __future__ import annotations

import asyncio
import os
import sys

import anyio

import galileo_async as galileo
from galileo_async.events import GoalReached

URL = sys.argv[1] if len(sys.argv) > 1 else os.environ.get("GALILEO_PORT", "sim://")
STOPS = 3


async def main() -> int:
    async with galileo.connect(URL) as robot:
        await robot.start_navigation(timeout=60)
        events = robot.events()  # subscribe before starting, so no arrival is missed
        await robot.start_patrol(dwell=1)
        print("patrolling")
        visited: list[int | None] = []
        with anyio.fail_after(180):  # works on Python 3.10 too
            async for event in events:
                if isinstance(event, GoalReached):
                    visited.append(event.target_id)
                    print(f"reached target {event.target_id}")
                    if len(visited) == STOPS:
                        break
        await robot.stop_patrol()  # 'm' 6: patrol stops, navigation stays open
        status = robot.status
        assert status is not None
        print(f"stopped; navigation still open: {status.navigating}")
    return 0


if __name__ == "__main__":
    sys.exit(asyncio.run(main()))
