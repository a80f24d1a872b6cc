"""``galileo fleet monitor`` in an 80x24 terminal (tmux): a row per robot, nothing wrapped, q."""

from __future__ import annotations

import io
import re
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
from rich.cells import cell_len
from rich.console import Console, RenderableType

from galileo_async import connect_fleet
from galileo_async.cli.fleet_view import COLUMNS, DROP_ORDER, MIN_MAP_ROWS, FleetView
from galileo_async.cli.map_model import MapModel
from tests.support.fake_device import make_status
from tests.support.tmux_support import keys, tmux_server, until

WIDTH, HEIGHT = 80, 24
SIM = "sim://?speed=20"
#: A small fleet; the long name takes columns that the narrow screen must then drop.
ROBOTS = ("alpha", "bravo", "charlie", "delta-long-robot-name")
#: The columns every width keeps.
KEPT = ("robot", "link", "goal")
#: Characters a line of the screen starts and ends with: panel borders, nothing past them.
STARTS, ENDS = "╭│╰", "╮│╯"


@pytest.fixture
def tmux() -> Iterator[list[str]]:
    """A tmux server of this test's own, an 80x24 pane."""
    yield from tmux_server(WIDTH, HEIGHT)


def _fleet_file(tmp_path: Path) -> Path:
    path = tmp_path / "fleet.toml"
    path.write_text("".join(f'[robots.{name}]\nport = "{SIM}"\n\n' for name in ROBOTS))
    return path


def _row(screen: str, name: str) -> str:
    (line,) = [line for line in screen.splitlines() if line.startswith(f"│ {name} ")]
    return line


def _every_robot_shown_up(screen: str) -> bool:
    """Each robot's row shows it up, with its power (its first status came)."""
    title = f"galileo fleet · {len(ROBOTS)} robots · up {len(ROBOTS)}"
    rows = [line for name in ROBOTS for line in screen.splitlines() if f"│ {name} " in line]
    return title in screen and len(rows) == len(ROBOTS) and all(" V " in row for row in rows)


async def test_fleet_monitor_at_80x24_keeps_every_robot_and_quits_on_q(
    tmux: list[str], tmp_path: Path
) -> None:
    fleet = _fleet_file(tmp_path)
    command = f"{sys.executable} -m galileo_async --fleet {fleet} fleet monitor"
    await keys(tmux, f"clear; {command}; echo monitor-exited-$?", "Enter")
    screen = await until(tmux, _every_robot_shown_up)

    lines = screen.splitlines()
    assert lines[0].startswith("╭")  # the title is on top: nothing scrolled off
    assert "galileo fleet · 4 robots" in lines[0]
    header = next(line for line in lines if line.startswith("│ robot "))
    headers = re.split(r"\s{2,}", header.strip("│ "))
    assert set(KEPT) <= set(headers), header
    assert headers == [column for column in COLUMNS if column in headers]  # in their order
    dropped = [column for column in COLUMNS if column not in headers]
    assert set(dropped) == set(DROP_ORDER[: len(dropped)]), header
    for name in ROBOTS:
        assert "up" in _row(screen, name).split()
    # Nothing wrapped or cut: every drawn line is a whole panel line of 80 cells, the map's
    # bottom border is the last, and the screen fits its 24 rows with no "..." crop.
    drawn = [line for line in lines if line.strip()]
    for line in drawn:
        assert (cell_len(line), line[0] in STARTS, line[-1] in ENDS) == (WIDTH, True, True), line
    assert drawn[-1].startswith("╰")
    assert "last minute" in drawn[-1]
    assert "─ map ─" in screen
    assert "..." not in screen
    assert len(drawn) < HEIGHT
    assert "q quit" in screen

    await keys(tmux, "q")
    screen = await until(tmux, lambda s: "monitor-exited-" in s)
    assert "monitor-exited-0" in screen, screen


def _render(renderable: RenderableType) -> list[str]:
    console = Console(width=WIDTH, file=io.StringIO(), color_system=None)
    console.print(renderable)
    text = console.file.getvalue()  # type: ignore[attr-defined]
    return str(text).splitlines()


@pytest.mark.parametrize(
    ("robots", "map_rows"),
    [(4, 14), (14, MIN_MAP_ROWS), (15, None)],
    ids=["the map fits the rows left", "the smallest map", "no room for the map"],
)
async def test_the_fleet_screen_fits_24_rows(robots: int, map_rows: int | None) -> None:
    names = [f"r{number:02d}" for number in range(robots)]
    async with connect_fleet(dict.fromkeys(names, SIM)) as fleet:
        view = FleetView(fleet, MapModel(), width=WIDTH, height=HEIGHT)
        view.latest = {name: make_status() for name in names}
        lines = _render(view.screen())
        view.height = None  # not a terminal: the map keeps its rows
        unbounded = _render(view.screen())
    assert len(lines) == (robots + 3) + (0 if map_rows is None else map_rows + 2)
    assert len(lines) < HEIGHT  # one row spare
    assert any("─ map ─" in line for line in lines) is (map_rows is not None)
    for name in names:
        assert sum(line.startswith(f"│ {name} ") for line in lines) == 1
    assert len(unbounded) == (robots + 3) + view.map_rows + 2


def test_q_ends_the_fleet_monitor_and_other_keys_do_not() -> None:
    view = FleetView(None, MapModel())  # type: ignore[arg-type]
    for key in "xm? ":
        view.press(key)
    assert not view.quit
    view.press("Q")
    assert view.quit
