"""Drive several robots at once from one event loop, with an anyio task group.

    python examples/fleet.py [URL ...]    # default: three simulators ($GALILEO_PORT or sim://)

Each ``sim://`` URL is its own simulated robot. A failing robot cancels the others' goals
(the driver sends cancel for each) and the error comes out of the task group.
"""

from __future__ import annotations

import os
import sys

import anyio

import galileo_async as galileo

URLS = sys.argv[1:] or [os.environ.get("GALILEO_PORT", "sim://")] * 3


async def tour(name: str, url: str, targets: list[int], results: dict[str, float]) -> None:
    """Connect, open navigation, visit ``targets``; record the total time."""
    async with galileo.connect(url) as robot:
        await robot.start_navigation(timeout=60)
        started = anyio.current_time()
        for target_id in targets:
            result = await robot.goto(target_id, timeout=120)
            print(f"{name}: arrived at {result.target_id} ({result.elapsed:.1f} s)")
        results[name] = anyio.current_time() - started


async def main() -> int:
    results: dict[str, float] = {}
    async with anyio.create_task_group() as group:
        for number, url in enumerate(URLS):
            # Each robot visits the targets in a different order.
            targets = [(number + step) % 6 for step in range(3)]
            group.start_soon(tour, f"robot-{number}", url, targets, results)
    for name, seconds in sorted(results.items()):
        print(f"{name} finished its tour in {seconds:.1f} s")
    return 0 if len(results) == len(URLS) else 1


if __name__ == "__main__":
    sys.exit(anyio.run(main))
