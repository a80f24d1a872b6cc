"""Drive by velocity from a script: forward, an arc, a turn on the spot; stopped on exit.

    python examples/teleop.py [URL]    # default: $GALILEO_PORT, else sim://

Some chassis hold the last speed command forever, others stop 1 to 3 s after it
(docs/protocol.md §6.5). ``robot.drive()`` re-sends the speed while its block runs and writes
one stop when the block is left, whatever way (an error, a cancellation, Ctrl-C).
"""

from __future__ import annotations

import asyncio
import os
import sys

import galileo_async as galileo

URL = sys.argv[1] if len(sys.argv) > 1 else os.environ.get("GALILEO_PORT", "sim://")


async def hold(robot: galileo.Robot, frames: int) -> galileo.GalileoStatus:
    """Let ``frames`` status frames go by (30 per simulated second); return the last."""
    seen = 0
    async for status in robot.statuses():
        seen += 1
        if seen >= frames:
            return status
    raise galileo.ConnectionLost("the status stream ended")


async def main() -> int:
    async with galileo.connect(URL) as robot:
        await robot.start_navigation(timeout=60)  # for a pose to print; driving works without
        async with robot.drive(linear=0.4, angular=0.0, rate=5.0) as d:  # m/s, rad/s, Hz
            status = await hold(robot, 45)
            print(f"forward: {status.current_speed_x:+.2f} m/s")
            d.set(angular=0.6)  # the linear speed is kept: an arc
            status = await hold(robot, 30)
            speed, turn = status.current_speed_x, status.current_speed_theta
            print(f"arc: {speed:+.2f} m/s, {turn:+.2f} rad/s")
            d.set(linear=0.0, angular=-0.9)
            status = await hold(robot, 30)
            print(f"turn on the spot: {status.current_speed_theta:+.2f} rad/s")
        status = await robot.wait_until(
            lambda s: s.current_speed_x == 0 and s.current_speed_theta == 0, timeout=10
        )
        pose = status.pose
        where = f" at ({pose.x:.2f}, {pose.y:.2f}), {pose.degrees:.0f}°" if pose else ""
        print(f"stopped{where}")
    return 0


if __name__ == "__main__":
    sys.exit(asyncio.run(main()))
