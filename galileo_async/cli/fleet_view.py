"""What ``galileo fleet`` shows: one row per robot, sorted and filtered, a summary, the map."""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from rich.console import Group, RenderableType
from rich.panel import Panel
from rich.table import Table
from rich.text import Text

from ..fleet.fleet import Fleet
from ..models import GalileoStatus, LinkState, TargetStatus
from .map_model import MapModel
from .map_render import map_panel

__all__ = ["SORT_KEYS", "FleetRow", "FleetView", "fleet_rows", "summary_line"]

#: Link state colours of the table.
_STATE_STYLES = {LinkState.UP: "green", LinkState.STALE: "yellow", LinkState.LOST: "red",
                 LinkState.CONNECTING: "dim", LinkState.CLOSED: "dim"}  # fmt: skip


@dataclass(frozen=True)
class FleetRow:
    """One robot's line of the fleet table, as plain values."""

    name: str
    state: LinkState
    age: float | None
    nav: str
    visual: str
    goal: int | None
    goal_state: str
    distance: float | None
    x: float | None
    y: float | None
    heading: float | None
    power: float | None
    last_event: str

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready values."""
        return {**self.__dict__, "state": self.state.value}


_NAMES: dict[Any, str] = {}


def _low(value: Any) -> str:
    """An enum's lower-case name ("—" for None), cached: a thousand robots a render."""
    text = _NAMES.get(value)
    if text is None:
        text = _NAMES[value] = "—" if value is None else str(getattr(value, "name", value)).lower()
    return text


def fleet_rows(
    fleet: Fleet, latest: dict[str, GalileoStatus], events: dict[str, str]
) -> list[FleetRow]:
    """A row per robot from its latest status and last event."""
    rows = []
    now = time.monotonic()
    for name in fleet:
        status, robot = latest.get(name), fleet.get(name)
        seen = None if robot is None else robot.link.last_frame_at
        state = fleet.state(name)
        age = None if seen is None else now - seen
        event = events.get(name) or _failure(fleet, name)
        if status is None:
            rows.append(FleetRow(name, state, age, "—", "—", None, "—", None, None, None, None,
                                 None, event))  # fmt: skip
            continue
        x, y, theta = status.current_pose_x, status.current_pose_y, status.current_angle
        if x is None or y is None or theta is None or x == y == theta == -1.0:
            x = y = theta = None  # unknown (GalileoStatus.pose)
        goal = status.target_num_id
        rows.append(FleetRow(
            name, state, age, _low(status.nav_status), _low(status.visual_status),
            goal if goal is not None and goal >= 0 else None, _low(status.target_status),
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
    """``N robots · connecting C · up U · stale S · lost L · closed D · goals running G``."""
    counts = {state: 0 for state in LinkState}
    for row in rows:
        counts[row.state] += 1
    running = sum(1 for row in rows if row.goal_state == TargetStatus.WORKING.name.lower())
    states = " · ".join(f"{state.value} {counts[state]}" for state in LinkState)
    return f"{len(rows)} robots · {states} · goals running {running}"


def _number(value: float | None, form: str) -> str:
    return "—" if value is None or math.isnan(value) else format(value, form)


def _table(rows: list[FleetRow], limit: int) -> Table:
    table = Table(box=None, pad_edge=False, header_style="bold")
    for column in ("robot", "link", "age", "nav", "visual", "goal", "distance", "pose", "power"):
        table.add_column(column, no_wrap=True, min_width=len(column))
    table.add_column("last event", no_wrap=True, overflow="ellipsis", max_width=30)
    for row in rows[:limit]:
        pose = "—" if row.x is None or row.y is None else (
            f"{row.x:+.2f} {row.y:+.2f} {_number(row.heading, '+.0f')}°")  # fmt: skip
        goal = "—" if row.goal is None else f"{row.goal} {row.goal_state}"
        table.add_row(
            row.name, Text(row.state.value, style=_STATE_STYLES[row.state]),
            "—" if row.age is None else f"{row.age * 1000:.0f} ms", row.nav, row.visual, goal,
            "—" if row.distance is None or row.distance < 0 else f"{row.distance:.2f} m", pose,
            "—" if row.power is None else f"{row.power:.1f} V", row.last_event,
        )  # fmt: skip
    return table


class FleetView:
    """The fleet monitor's screen: summary, table (sorted, filtered, cut) and the map."""

    def __init__(
        self, fleet: Fleet, model: MapModel, *, sort: str = "name", match: str = "",
        states: set[LinkState] | None = None, limit: int = 20, map_rows: int = 16,
    ) -> None:  # fmt: skip
        self.fleet = fleet
        self.model = model
        self.sort = sort
        self.match = match
        self.states = states
        self.limit = limit
        self.map_rows = map_rows
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
        title = f"galileo fleet · {summary_line(every)}"
        return Panel(_table(rows, self.limit), title=title, subtitle=f"sort {self.sort}{shown}")

    def screen(self) -> RenderableType:
        """Move the changed robots on the map, then the whole screen."""
        changed, self.changed = self.changed, {}
        for name, status in changed.items():
            self.model.update(name, status)
        return Group(self.table(), map_panel(self.model, self.map_rows))
