"""A fleet in one process: connect_fleet, one merged status stream, one operation per robot.

    python examples/fleet_dashboard.py [N]   # N simulated robots ($GALILEO_PORT or sim://)

Every robot is connected at once; a dashboard task reads ONE coalesced stream of the whole
fleet (each robot's newest status, never a backlog) and prints a line per robot at most
twice a second, while ``fleet.each`` sends every robot to a target of its own.
"""

from __future__ import annotations

import os
import sys

import anyio

import galileo_async as galileo

COUNT = int(sys.argv[1]) if len(sys.argv) > 1 else 4
URL = os.environ.get("GALILEO_PORT", "sim://")
#: Seconds between two lines of the same robot.
LINE_EVERY = 0.5


async def dashboard(fleet: galileo.Fleet) -> None:
    """Print each robot's pose and goal from the merged stream, at most every LINE_EVERY s."""
    printed: dict[str, float] = {}
    async for name, status in fleet.statuses():
        now = anyio.current_time()
        if now - printed.get(name, -LINE_EVERY) < LINE_EVERY:
            continue  # this robot's next line comes later; the stream keeps only its newest
        printed[name] = now
        pose = status.pose
        where = "pose unknown" if pose is None else f"({pose.x:+.2f}, {pose.y:+.2f})"
        goal = status.target_status.name.lower() if status.target_status is not None else "—"
        print(f"{name}: {where} target {status.target_num_id} {goal}")


async def events(fleet: galileo.Fleet) -> None:
    """Print the goal events of every robot, from ONE merged event stream."""
    async for name, event in fleet.events():
        if event.name.startswith("Goal"):
            print(f"{name}: event {event.name}")


async def main() -> int:
    ports = {f"robot-{number}": URL for number in range(COUNT)}
    async with galileo.connect_fleet(ports) as fleet:
        print(f"{len(fleet)} robots: {', '.join(fleet)}; states {set(fleet.states().values())}")
        async with anyio.create_task_group() as group:
            group.start_soon(dashboard, fleet)
            group.start_soon(events, fleet)
            opened = await fleet.each(lambda robot: robot.start_navigation(timeout=60))
            names = [name for name, result in opened.items() if result.ok]
            targets = {name: number % 6 for number, name in enumerate(fleet)}
            results = await fleet.each(
                lambda robot: robot.goto(targets[fleet.name_of(robot)]), names=names
            )
            group.cancel_scope.cancel()
    for name, result in results.items():
        if result.ok and result.value is not None:
            print(f"{name}: arrived at {result.value.target_id} in {result.value.elapsed:.1f} s")
        else:
            print(f"{name}: failed: {result.error!r}")
    return 0 if all(result.ok for result in results.values()) else 1


if __name__ == "__main__":
    sys.exit(anyio.run(main))
