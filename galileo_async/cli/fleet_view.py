"""What ``galileo fleet`` shows: one row per robot, sorted and filtered, a summary, the map."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, cast

from rich.console import Group, RenderableType
from rich.panel import Panel
from rich.table import Table
from rich.text import Text

from ..fleet.fleet import Fleet
from ..models import GalileoStatus, LinkState, TargetStatus
from .map_model import MapModel
from .map_render import map_panel
from .render import LINK_STATE_STYLES

__all__ = [
    "COLUMNS",
    "DROP_ORDER",
    "MIN_MAP_ROWS",
    "SORT_KEYS",
    "FleetRow",
    "FleetView",
    "fleet_rows",
    "row_cells",
    "summary_line",
]


@dataclass(frozen=True)
class FleetRow:
    """One robot's line of the fleet table, as plain values."""

    name: str
    state: LinkState
    age: float | None
    nav: str
    visual: str
    charge: str
    goal: int | None
    goal_state: str
    distance: float | None
    x: float | None
    y: float | None
    heading: float | None
    power: float | None
    last_event: str


#: Keyed by (type, value): members of different IntEnums with one value compare equal.
_NAMES: dict[tuple[type, Any], str] = {}


def _low(value: Any) -> str:
    """An enum's lower-case name ("—" for None), cached: a thousand robots a render."""
    key = (type(value), value)
    text = _NAMES.get(key)
    if text is None:
        text = _NAMES[key] = "—" if value is None else str(getattr(value, "name", value)).lower()
    return text


def fleet_rows(
    fleet: Fleet, latest: dict[str, GalileoStatus], events: dict[str, str]
) -> list[FleetRow]:
    """A row per robot from its latest status and last event."""
    rows = []
    for name in fleet:
        status, robot = latest.get(name), fleet.get(name)
        age = None if robot is None else robot.link.last_frame_age
        state = fleet.state(name)
        event = events.get(name) or _failure(fleet, name)
        if status is None:
            rows.append(FleetRow(name, state, age, "—", "—", "—", None, "—", None, None, None, None,
                                 None, event))  # fmt: skip
            continue
        x, y, theta = status.current_pose_x, status.current_pose_y, status.current_angle
        if x is None or y is None or theta is None or x == y == theta == -1.0:
            x = y = theta = None  # unknown (GalileoStatus.pose)
        goal = status.target_num_id
        rows.append(FleetRow(
            name, state, age, _low(status.nav_status), _low(status.visual_status),
            _low(status.charge_status), goal if goal is not None and goal >= 0 else None,
            _low(status.target_status),
            status.target_distance, x, y, None if theta is None else math.degrees(theta),
            status.power, event,
        ))  # fmt: skip
    return rows


def _failure(fleet: Fleet, name: str) -> str:
    error = fleet.error(name)
    return "" if error is None else f"connect failed: {error}"


def _missing_last(value: float | None) -> tuple[bool, float]:
    return (value is None or math.isnan(value), value or 0.0)


#: Sort keys of --sort and what each sorts on.
SORT_KEYS: dict[str, Callable[[FleetRow], Any]] = {
    "name": lambda row: row.name,
    "state": lambda row: (list(LinkState).index(row.state), row.name),
    "age": lambda row: _missing_last(row.age),
    "goal": lambda row: (row.goal is None, row.goal or 0, row.name),
    "distance": lambda row: _missing_last(row.distance),
    "power": lambda row: _missing_last(row.power),
}


def summary_line(rows: list[FleetRow]) -> str:
    """``N robots · up U · lost L · goals running G``: the link states with robots in them."""
    counts = {state: 0 for state in LinkState}
    for row in rows:
        counts[row.state] += 1
    running = sum(1 for row in rows if row.goal_state == TargetStatus.WORKING.name.lower())
    states = " · ".join(f"{state.value} {counts[state]}" for state in LinkState if counts[state])
    return " · ".join(part for part in (f"{len(rows)} robots", states, f"goals running {running}")
                      if part)  # fmt: skip


def _number(value: float | None, form: str) -> str:
    return "—" if value is None or math.isnan(value) else format(value, form)


#: Columns of the table in order; the narrow screen drops them from the end of DROP_ORDER.
COLUMNS = ("robot", "link", "age", "nav", "visual", "charge", "goal", "distance", "pose",
           "power", "last event")  # fmt: skip
#: Least important first: what a narrow screen drops, one column at a time, until it fits.
DROP_ORDER = ("age", "last event", "visual", "charge", "pose", "power", "distance", "nav")
#: Map rows below which a short screen shows the table without the map.
MIN_MAP_ROWS = 4


def row_cells(row: FleetRow) -> dict[str, str | Text]:
    pose = "—" if row.x is None or row.y is None else (
        f"{row.x:+.2f} {row.y:+.2f} {_number(row.heading, '+.0f')}°")  # fmt: skip
    return {
        "robot": row.name, "link": Text(row.state.value, style=LINK_STATE_STYLES[row.state]),
        "age": "—" if row.age is None else f"{row.age * 1000:.0f} ms", "nav": row.nav,
        "visual": row.visual, "charge": row.charge,
        "goal": "—" if row.goal is None else f"{row.goal} {row.goal_state}",
        "distance": "—" if row.distance is None or row.distance < 0 else f"{row.distance:.2f} m",
        "pose": pose, "power": "—" if row.power is None else f"{row.power:.1f} V",
        "last event": row.last_event,
    }  # fmt: skip


def _columns(cells: list[dict[str, str | Text]], width: int) -> list[str]:
    """The columns that fit ``width`` (2 spaces between), dropping by DROP_ORDER."""
    widths = {name: max([len(name), *(len(str(cell[name])) for cell in cells)]) for name in COLUMNS}
    widths["last event"] = min(widths["last event"], 30)
    shown = list(COLUMNS)
    for name in DROP_ORDER:
        if sum(widths[column] for column in shown) + 2 * (len(shown) - 1) <= width:
            break
        shown.remove(name)
    return shown


def _table(rows: list[FleetRow], limit: int, width: int) -> Table:
    cells = [row_cells(row) for row in rows[:limit]]
    table = Table(box=None, pad_edge=False, header_style="bold", padding=(0, 1))
    shown = _columns(cells, width)
    for column in shown:
        if column == "last event":
            table.add_column(column, no_wrap=True, overflow="ellipsis", max_width=30)
        else:
            table.add_column(column, no_wrap=True, min_width=len(column))
    for cell in cells:
        table.add_row(*(cell[column] for column in shown))
    return table


class FleetView:
    """The fleet monitor's screen: summary, table (sorted, filtered, cut) and the map."""

    def __init__(
        self, fleet: Fleet, model: MapModel, *, sort: str = "name", match: str = "",
        states: set[LinkState] | None = None, limit: int = 20, map_rows: int = 16,
        width: int = 200, height: int | None = None,
    ) -> None:  # fmt: skip
        self.fleet = fleet
        self.model = model
        self.sort = sort
        self.match = match
        self.states = states
        self.limit = limit
        self.map_rows = map_rows
        #: Columns of the screen: the table drops its least important columns to fit.
        self.width = width
        #: Rows of the screen (None: not a terminal): the map shrinks to the rows left.
        self.height = height
        #: Hint of the keys shown under the table (the live monitor's: ``q quit``).
        self.keys_hint = ""
        #: Set once q was pressed (the live monitor then ends).
        self.quit = False
        #: Newest statuses not yet on the map, and every robot's latest.
        self.changed: dict[str, GalileoStatus] = {}
        self.latest: dict[str, GalileoStatus] = {}
        self.events: dict[str, str] = {}

    def rows(self, every: list[FleetRow] | None = None) -> list[FleetRow]:
        """Every robot (of ``every``, else the fleet now) that passes the filters, sorted."""
        rows = fleet_rows(self.fleet, self.latest, self.events) if every is None else every
        if self.match:
            rows = [row for row in rows if self.match in row.name]
        if self.states:
            rows = [row for row in rows if row.state in self.states]
        return sorted(rows, key=SORT_KEYS[self.sort])

    def table(self) -> Panel:
        """The summary (title) and the table of the robots that pass the filters."""
        every = fleet_rows(self.fleet, self.latest, self.events)
        rows = self.rows(every)
        more = len(rows) - self.limit
        shown = f" · showing {self.limit} of {len(rows)} (--rows)" if more > 0 else ""
        keys = f" · {self.keys_hint}" if self.keys_hint else ""
        title = f"galileo fleet · {summary_line(every)}"
        # The panel's border and padding take 4 columns.
        table = _table(rows, self.limit, self.width - 4)
        return Panel(table, title=title, subtitle=f"sort {self.sort}{shown}{keys}")

    def press(self, key: str) -> None:
        """Apply one key typed in the live monitor: q quits, others are ignored."""
        if key in ("q", "Q"):
            self.quit = True

    def screen(self) -> RenderableType:
        """Move the changed robots on the map, then the screen: the map fits the rows left."""
        changed, self.changed = self.changed, {}
        for name, status in changed.items():
            self.model.update(name, status)
        table = self.table()
        map_rows = self.map_rows
        if self.height is not None:
            # The table's borders and header, the map's borders, one spare row.
            robots = cast(Table, table.renderable).row_count
            map_rows = min(map_rows, self.height - (robots + 3) - 2 - 1)
            if map_rows < MIN_MAP_ROWS:
                return table
        return Group(table, map_panel(self.model, map_rows))
