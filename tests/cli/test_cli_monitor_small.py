"""``galileo monitor`` in an 80x24 terminal (tmux): the map shows, keys q, m and ? work."""

from __future__ import annotations

import io
import json
import os
import re
import subprocess
import sys
from collections.abc import Iterator
from typing import Any

import anyio
import pytest
from rich.console import Console

import galileo_async as galileo
from galileo_async.cli.map_model import MapModel
from galileo_async.cli.monitor_screen import MonitorView
from galileo_async.errors import GoalCancelled
from galileo_async.models import (
    ChargeStatus,
    GalileoStatus,
    LinkState,
    MapStatus,
    NavStatus,
    StatusLayout,
    TargetStatus,
    VisualStatus,
)
from galileo_async.sim import Simulator
from galileo_async.transports import LinkStats
from tests.cli.test_cli_served import GALILEO, WAIT
from tests.support.tmux_support import keys, tmux_server, until

COLUMNS, ROWS = 80, 24
SIM_URL = "sim://?speed=4&visual_init_time=0.5"


@pytest.fixture
def tmux() -> Iterator[list[str]]:
    """A tmux server of this test's own, an 80x24 pane."""
    yield from tmux_server(COLUMNS, ROWS)


def _coloured(screen: str, word: str, colour: str) -> bool:
    """Whether ``word`` shows on the captured ``screen`` in SGR colour ``colour`` (32 green)."""
    for match in re.finditer(r"((?:\x1b\[[0-9;]*m)+)" + re.escape(word), screen):
        if colour in re.findall(r"[0-9]+", match.group(1)):
            return True
    return False


async def _start_monitor(tmux: list[str], url: str) -> None:
    monitor = f"{sys.executable} -m galileo_async -p {url} monitor; echo monitor-exited-$?"
    await keys(tmux, "clear; " + monitor, "Enter")


async def test_monitor_at_80x24_shows_the_map_and_answers_its_keys(tmux: list[str]) -> None:
    await _start_monitor(tmux, f"'{SIM_URL}'")
    screen = await until(tmux, lambda s: "─ map ─" in s and "◆" in s)
    assert "q quit" in screen
    lines = screen.splitlines()
    assert lines[0].startswith("galileo monitor")  # nothing scrolled off the top
    await keys(tmux, "xyz")  # not echoed over the screen
    await keys(tmux, "m")
    screen = await until(tmux, lambda s: "─ map ─" not in s)
    assert "xyz" not in screen
    await keys(tmux, "m")
    await until(tmux, lambda s: "─ map ─" in s)
    await keys(tmux, "?")
    await until(tmux, lambda s: "show or hide the map" in s)
    await keys(tmux, "?")
    await until(tmux, lambda s: "─ map ─" in s)
    await keys(tmux, "q")
    await until(tmux, lambda s: "monitor-exited-0" in s)


async def _goto_cancelled(robot: galileo.Robot) -> None:
    with pytest.raises(GoalCancelled):
        await robot.goto(1)


async def test_monitor_colours_follow_the_states(tmux: list[str]) -> None:
    async with Simulator.from_url(SIM_URL) as simulator:
        server = await simulator.serve_tcp()
        try:
            url = f"socket://127.0.0.1:{server.sockets[0].getsockname()[1]}"
            await _start_monitor(tmux, url)
            await until(tmux, lambda s: "nav closed" in s)
            async with galileo.connect(url, map_targets=6) as robot:
                await robot.start_navigation(timeout=WAIT)
                await until(tmux, lambda s: _coloured(s, "open", "32"), escapes=True)
                async with anyio.create_task_group() as group:
                    group.start_soon(_goto_cancelled, robot)
                    await until(tmux, lambda s: _coloured(s, "working", "36"), escapes=True)
                    await robot.cancel()
            await keys(tmux, "q")
            await until(tmux, lambda s: "monitor-exited-0" in s)
        finally:
            server.close()


def test_monitor_json_prints_status_lines() -> None:
    env = {key: value for key, value in os.environ.items() if key != "GALILEO_PORT"}
    result = subprocess.run(
        [*GALILEO, "--port", "sim://?speed=20", "monitor", "--json", "--duration", "1.5"],
        capture_output=True, text=True, timeout=WAIT, env=env, check=False,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    lines = [json.loads(line) for line in result.stdout.splitlines()]
    assert any("status" in line for line in lines)


#: A status whose every value the small monitor shows is as long as it gets.
WIDEST = GalileoStatus(
    layout=StatusLayout.V2_TRUNCATED, nav_status=NavStatus.CLOSED,
    visual_status=VisualStatus.NOT_INITIALISED, map_status=MapStatus.MAPPING,
    charge_status=ChargeStatus.FINDING_DOCK, loop_status=1, power=124.28, target_num_id=255,
    target_status=TargetStatus.WORKING, target_distance=999.99, current_pose_x=-999.99,
    current_pose_y=-999.99, current_angle=-3.14, current_speed_x=-9.99,
    current_speed_theta=-9.99, time_stamp=2**31 - 1,
)  # fmt: skip


def lines_at(width: int, screen: Any) -> list[str]:
    """The lines of ``screen`` in a terminal ``width`` columns wide, no colours."""
    console = Console(width=width, file=io.StringIO(), color_system=None, height=ROWS)
    console.print(screen)
    return [line.rstrip() for line in console.file.getvalue().splitlines()]  # type: ignore[attr-defined]


@pytest.mark.parametrize("state", list(LinkState))
@pytest.mark.parametrize(
    "status",
    [WIDEST, WIDEST.model_copy(update={"current_speed_x": None, "current_speed_theta": None})],
    ids=["widest", "no speed (udp://)"],
)
def test_every_line_of_the_small_monitor_fits_80_columns(
    status: GalileoStatus, state: LinkState
) -> None:
    link = LinkStats(state=state, connected=state is LinkState.UP, frames=10)
    screen = MonitorView().screen(
        status, link, [], url="socket://10.0.0.5:4001", model=MapModel(), rows=ROWS
    )
    narrow, wide = lines_at(COLUMNS, screen)[:4], lines_at(200, screen)[:4]
    assert narrow == wide  # nothing cut at 80 columns
    assert narrow[0].startswith("galileo monitor")
    assert narrow[2].endswith("rad/s" if status.current_speed_x is not None else "speed n/a")
    assert narrow[3].endswith(f"link {state.value}")  # LinkState's own names


async def test_monitor_at_80x24_shows_every_line_whole(tmux: list[str]) -> None:
    async with Simulator.from_url(SIM_URL) as simulator:
        server = await simulator.serve_tcp()
        try:
            url = f"socket://127.0.0.1:{server.sockets[0].getsockname()[1]}"
            await _start_monitor(tmux, url)
            await until(tmux, lambda s: "nav closed" in s)
            async with galileo.connect(url, map_targets=6) as robot:
                await robot.start_navigation(timeout=WAIT)
                # Navigation open: the pose is known, so every field of each line shows.
                screen = await until(tmux, lambda s: "heading" in s)
            lines = screen.splitlines()
            assert lines[0].startswith("galileo monitor")
            motion = next(line for line in lines if "heading" in line)
            assert motion.rstrip().endswith("rad/s"), motion
            goal = next(line for line in lines if line.startswith("goal "))
            assert goal.rstrip().endswith("link up"), goal
            await keys(tmux, "q")
            await until(tmux, lambda s: "monitor-exited-0" in s)
        finally:
            server.close()
