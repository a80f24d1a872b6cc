"""Print a line per status change and every event, for a while, with statuses() and events().

python examples/monitor.py [URL] [SECONDS]    # default: $GALILEO_PORT or sim://, 5 s
"""

from __future__ import annotations

import os
import sys
from collections.abc import AsyncIterator

import anyio

import galileo_async as galileo
from galileo_async.events import Event

URL = sys.argv[1] if len(sys.argv) > 1 else os.environ.get("GALILEO_PORT", "sim://")
SECONDS = float(sys.argv[2]) if len(sys.argv) > 2 else 5.0


async def print_changes(statuses: AsyncIterator[galileo.GalileoStatus]) -> None:
    """Print the goal state whenever it changes (statuses() skips to the newest)."""
    last = None
    async for status in statuses:
        now = (status.nav_status, status.target_num_id, status.target_status)
        if now != last:
            pose = status.pose
            where = f"at ({pose.x:.2f}, {pose.y:.2f})" if pose else "pose unknown"
            nav = "open" if status.navigating else "closed"
            goal = "none" if status.target_status is None else status.target_status.name.lower()
            print(f"frame {status.time_stamp}: nav {nav}, target {now[1]} {goal}, {where}")
            last = now


async def print_events(events: AsyncIterator[Event]) -> None:
    async for event in events:
        print(f"event: {event.name}")


async def drive(robot: galileo.Robot) -> None:
    """Give the monitor something to see."""
    await robot.start_navigation(timeout=60)
    await robot.goto(0, timeout=60)


async def main() -> int:
    async with galileo.connect(URL) as robot, anyio.create_task_group() as group:
        # Subscribe here, before anything is sent, so the first transitions are seen.
        group.start_soon(print_changes, robot.statuses())
        group.start_soon(print_events, robot.events())
        with anyio.move_on_after(SECONDS) as scope:
            await drive(robot)
        if scope.cancelled_caught:
            print(f"still driving after {SECONDS} s; the goal was cancelled")
        print(f"link: {robot.link.frames} frames, {robot.link.lost_frames} lost")
        group.cancel_scope.cancel()
    return 0


if __name__ == "__main__":
    sys.exit(anyio.run(main))
