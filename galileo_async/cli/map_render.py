"""The map panel: a MapModel drawn top-down in terminal cells (rich), auto-scaled."""

from __future__ import annotations

import io
import math
from collections.abc import Callable, Iterator
from pathlib import Path

from rich.console import Console, ConsoleOptions, RenderableType, RenderResult
from rich.panel import Panel
from rich.segment import Segment
from rich.style import Style

from .map_model import Bounds, MapModel

__all__ = ["ARROWS", "MapView", "arrow_for", "map_panel", "save_svg"]

#: Heading arrows, counter-clockwise from east (theta = 0) in eighths of a turn.
ARROWS = "→↗↑↖←↙↓↘"
#: Rows of the map panel unless the console says otherwise.
DEFAULT_ROWS = 16
#: A terminal cell is about twice as tall as it is wide.
CELL_ASPECT = 2.0
#: Trail styles from newest to oldest (the trail fades over its minute).
TRAIL_STYLES = (Style(color="cyan"), Style(color="grey62"), Style(color="grey42"),
                Style(color="grey30"))  # fmt: skip
TARGET_STYLE = Style(color="green")
GOAL_STYLE = Style(color="black", bgcolor="yellow", bold=True)
ROBOT_STYLE = Style(color="bright_white", bold=True)
#: Robots drawn with their name beside them; more are drawn as arrows only.
MAX_LABELS = 12


def arrow_for(theta: float) -> str:
    """The arrow nearest to heading ``theta`` (radians, counter-clockwise from +x)."""
    eighth = round(theta / (math.pi / 4)) % 8
    return ARROWS[eighth]


class MapView:
    """A renderable of ``model``: ``rows`` tall, as wide as the console allows."""

    def __init__(
        self, model: MapModel, rows: int = DEFAULT_ROWS, bounds: Bounds | None = None
    ) -> None:
        self.model = model
        self.rows = rows
        self.bounds = bounds

    def __rich_console__(self, console: Console, options: ConsoleOptions) -> RenderResult:
        width, rows = max(8, options.max_width), max(4, options.height or self.rows)
        cells: list[list[tuple[str, Style | None]]] = [[(" ", None)] * width for _ in range(rows)]
        place = _placer(self.bounds or self.model.bounds(), width, rows)
        now = self.model.clock()
        horizon = self.model.trail_seconds or 1.0
        for track in self.model.robots.values():
            for when, x, y in track.trail:
                spot = place(x, y)
                if spot is not None:
                    age = min(
                        len(TRAIL_STYLES) - 1, int(len(TRAIL_STYLES) * (now - when) / horizon)
                    )
                    cells[spot[1]][spot[0]] = ("·", TRAIL_STYLES[max(0, age)])
        goals = self.model.goals()
        for target in self.model.targets.values():
            spot = place(target.x, target.y)
            if spot is not None:
                label = f"◆{target.target_id}"
                _write(
                    cells, spot, label, GOAL_STYLE if target.target_id in goals else TARGET_STYLE
                )
        labelled = len(self.model.robots) <= MAX_LABELS
        for track in self.model.robots.values():
            spot = place(track.x, track.y)
            if spot is not None:
                text = arrow_for(track.theta) + (f" {track.name}" if labelled else "")
                _write(cells, spot, text, ROBOT_STYLE)
        for index, row in enumerate(cells):
            yield from _segments(row)
            if index < rows - 1:
                yield Segment.line()


_Place = Callable[[float, float], "tuple[int, int] | None"]


def _placer(bounds: Bounds, width: int, rows: int) -> _Place:
    """Map metres to (column, row), one scale on both axes (cells are twice as tall)."""
    scale = min((width - 1) / bounds.width, (rows - 1) * CELL_ASPECT / bounds.height)
    x_mid, y_mid = (bounds.x_min + bounds.x_max) / 2, (bounds.y_min + bounds.y_max) / 2

    def place(x: float, y: float) -> tuple[int, int] | None:
        column = round((width - 1) / 2 + (x - x_mid) * scale)
        row = round((rows - 1) / 2 - (y - y_mid) * scale / CELL_ASPECT)
        if 0 <= column < width and 0 <= row < rows:
            return column, row
        return None

    return place


def _write(
    cells: list[list[tuple[str, Style | None]]], spot: tuple[int, int], text: str, style: Style
) -> None:
    column, row = spot
    line = cells[row]
    for offset, char in enumerate(text):
        if column + offset < len(line):
            line[column + offset] = (char, style)


def _segments(row: list[tuple[str, Style | None]]) -> Iterator[Segment]:
    """One segment per run of cells of the same style."""
    text, style = "", row[0][1]
    for char, cell_style in row:
        if cell_style is not style:
            yield Segment(text, style)
            text, style = "", cell_style
        text += char
    yield Segment(text, style)


def map_panel(model: MapModel, rows: int = DEFAULT_ROWS, title: str = "map") -> Panel:
    """The map in a titled panel; the subtitle gives the scale and what the marks mean."""
    bounds = model.bounds()
    subtitle = f"{bounds.width:.1f} × {bounds.height:.1f} m · ◆ target · · last minute"
    return Panel(MapView(model, rows, bounds), title=title, subtitle=subtitle, height=rows + 2)


def save_svg(renderable: RenderableType, path: Path, *, width: int = 120, title: str = "") -> None:
    """Write ``renderable`` as the terminal would show it, as an SVG file (for bug reports)."""
    console = Console(record=True, width=width, file=io.StringIO(), force_terminal=True)
    console.print(renderable)
    console.save_svg(str(path), title=title or "galileo")
