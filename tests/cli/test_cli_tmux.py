"""``galileo monitor`` as a person sees it: run in tmux against the simulator, read the screen.

The test drives the simulated robot over its own connection while the monitor, in a tmux
pane of a tmux server of its own (``-L``), shows it; the map panel must show the robot's
arrow at different places as it drives, and the trail it leaves.
"""

from __future__ import annotations

import sys
from collections.abc import Iterator
from pathlib import Path

import anyio
import pytest

import galileo_async as galileo
from galileo_async.cli.map_render import ARROWS
from galileo_async.sim import Simulator
from tests.support.tmux_support import screen, tmux_server

#: Bound, in real seconds, of each wait on the screen.
WAIT = 30.0
#: The pane's size: the dashboard and the map fit in it.
COLUMNS, ROWS = 120, 60
#: target 1 of the default map is 5 m away: a drive of several seconds at speed 4.
SIM_URL = "sim://?speed=4&visual_init_time=0.5"


@pytest.fixture
def tmux() -> Iterator[list[str]]:
    """A tmux server of this test's own."""
    yield from tmux_server(COLUMNS, ROWS)


def _map_rows(screen: str) -> list[str]:
    """The lines inside the map panel of a captured screen."""
    lines = screen.splitlines()
    top = next((i for i, line in enumerate(lines) if "─ map ─" in line), None)
    if top is None:
        return []
    inside = []
    for line in lines[top + 1 :]:
        if line.lstrip().startswith("╰"):
            break
        inside.append(line)
    return inside


def _robot_at(rows: list[str]) -> tuple[int, int] | None:
    """(row, column) of the robot's arrow on the map, or None while it is not drawn."""
    for row, line in enumerate(rows):
        for column, char in enumerate(line):
            if char in ARROWS:
                return row, column
    return None


async def test_monitor_map_shows_the_robot_moving(tmux: list[str], tmp_path: Path) -> None:
    async with Simulator.from_url(SIM_URL) as simulator:
        server = await simulator.serve_tcp()
        try:
            port = server.sockets[0].getsockname()[1]
            url = f"socket://127.0.0.1:{port}"
            # Over socket:// the monitor knows the map's targets from a --targets file.
            targets = tmp_path / "targets.csv"
            rows = [f"{i},{x},{y}" for i, (x, y) in enumerate(simulator.state.targets)]
            targets.write_text("id,x,y\n" + "\n".join(rows) + "\n")
            monitor = f"{sys.executable} -m galileo_async -p {url} monitor --targets {targets}"
            await anyio.run_process([*tmux, "send-keys", "-t", "main", monitor, "Enter"])
            async with galileo.connect(url, map_targets=6) as robot:
                await robot.start_navigation(timeout=WAIT)
                places: set[tuple[int, int]] = set()
                trail = False
                # The simulator's map: target 1's label, seen while the robot is not on it
                # (once there, its arrow covers the label).
                target_shown = False
                # The monitor is up (its map shows the robot) before the robot moves, however
                # long the process took to start; then the robot drives back and forth until
                # the screen has shown what it must, however slowly it is read.

                async def drive() -> None:
                    while True:
                        for target in (1, 2):
                            await robot.goto(target)

                with anyio.fail_after(WAIT):
                    # A tmux screen has no change notification: read it again until then.
                    while _robot_at(_map_rows(await screen(tmux))) is None:  # noqa: ASYNC110
                        await anyio.sleep(0.1)
                    async with anyio.create_task_group() as group:
                        group.start_soon(drive)
                        while len(places) < 3 or not trail or not target_shown:
                            rows = _map_rows(await screen(tmux))
                            spot = _robot_at(rows)
                            if spot is not None:
                                places.add(spot)
                            trail = any("·" in line for line in rows)
                            target_shown = target_shown or "◆1" in "".join(rows)
                            await anyio.sleep(0.2)
                        group.cancel_scope.cancel()
            await anyio.run_process([*tmux, "send-keys", "-t", "main", "C-c", ""])
        finally:
            server.close()


async def test_demo_shows_the_map_as_the_robot_drives(tmux: list[str]) -> None:
    demo = f"{sys.executable} -m galileo_async demo"
    await anyio.run_process([*tmux, "send-keys", "-t", "main", demo, "Enter"])
    places: set[tuple[int, int]] = set()
    with anyio.fail_after(2 * WAIT):
        while len(places) < 2:
            spot = _robot_at(_map_rows(await screen(tmux)))
            if spot is not None:
                places.add(spot)
            await anyio.sleep(0.1)
        # A screen has no event to wait on: poll it until the demo ends, its steps all done.
        while "total" not in await screen(tmux):  # noqa: ASYNC110
            await anyio.sleep(0.2)
    assert "✔" in await screen(tmux)
