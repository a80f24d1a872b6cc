"""Run a small patrol mission: checked first, a line per step, the robot stopped on Ctrl-C.

python examples/mission.py [URL]    # default: $GALILEO_PORT, else sim://
Needs the extra [missions] (PyYAML) for the mission text below.
"""

from __future__ import annotations

import asyncio
import os
import sys

import galileo_async as galileo
from galileo_async.missions import (
    MissionEvent,
    StepEnded,
    check_mission,
    parse_mission,
)

URL = sys.argv[1] if len(sys.argv) > 1 else os.environ.get("GALILEO_PORT", "sim://")

PATROL = """
mission: two-lap patrol
steps:
  - loop:
      count: 2
      steps:
        - goto: 1
          on_failure: retry 1
        - dwell: 1
        - goto: 2
          on_failure: skip
  - goto: 0
    name: home
"""


def show(event: MissionEvent) -> None:
    if isinstance(event, StepEnded):
        step = event.step
        print(f"{step.path} {step.action}: {step.ending} ({step.distance_m:.1f} m)")


async def main() -> int:
    mission = parse_mission(PATROL, source="examples/mission.py")
    async with galileo.connect(URL) as robot:
        await robot.start_navigation(timeout=60)
        problems = await check_mission(mission, robot=robot)  # before anything moves
        errors = [problem for problem in problems if problem.severity == "error"]
        for problem in problems:
            print(f"check: {problem}")
        if errors:
            return 2
        report = await robot.run_mission(mission, on_progress=show)
        print(f"mission {report.mission!r}: {report.ending}, {report.loops_done} laps")
    return 0 if report.ending == "completed" else 1


if __name__ == "__main__":
    try:
        sys.exit(asyncio.run(main()))
    except KeyboardInterrupt:  # run_mission stopped the robot on its way out
        sys.exit(130)
