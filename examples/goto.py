"""Go to targets with a timeout, telling apart every way a goal can end.

python examples/goto.py [URL]      # default: $GALILEO_PORT, else sim:// (the simulator)
"""

from __future__ import annotations

import asyncio
import os
import sys

import galileo_async as galileo

URL = sys.argv[1] if len(sys.argv) > 1 else os.environ.get("GALILEO_PORT", "sim://")


async def go(robot: galileo.Robot, target_id: int) -> bool:
    """Send the robot to ``target_id``; print what happened; True when it arrived."""
    try:
        result = await robot.goto(target_id, timeout=120)
    except galileo.GoalRejected as exc:
        print(f"goal {exc.target_id} rejected: no such target, or unreachable")
    except galileo.GoalAborted as exc:
        print(f"goal {exc.target_id} aborted {exc.distance or 0:.2f} m short of the target")
    except galileo.GoalCancelled as exc:
        print(f"goal {exc.target_id} {'preempted' if exc.preempted else 'cancelled'}")
    except TimeoutError as exc:  # the robot was told to cancel before this was raised
        print(f"goal {target_id} timed out: {exc}")
    else:
        print(f"arrived at {result.target_id} after {result.elapsed:.1f} s")
        return True
    return False


async def main() -> int:
    try:
        async with galileo.connect(URL) as robot:
            await robot.start_navigation(timeout=60)
            arrived = [await go(robot, target_id) for target_id in (1, 2, 42)]
    except galileo.GalileoConnectionError as exc:
        print(f"link problem: {exc}", file=sys.stderr)
        return 1
    # Target 42 is not on the simulator's six-target map: two out of three is a success.
    return 0 if arrived == [True, True, False] else 1


if __name__ == "__main__":
    sys.exit(asyncio.run(main()))
