"""How the CLI shows statuses, link statistics and events: JSON-ready dicts and rich tables."""

from __future__ import annotations

import dataclasses
import enum
import math
from collections.abc import Iterable
from typing import Any

from rich.console import Group, RenderableType
from rich.panel import Panel
from rich.table import Table

from ..events import ConnectionLostEvent, ConnectionRestored, Event, LinkRestored, LinkStaleEvent
from ..models import GalileoStatus, LinkState

__all__ = [
    "DECIMALS",
    "LINK_STATE_STYLES",
    "dashboard",
    "event_dict",
    "event_text",
    "goal_line",
    "link_dict",
    "link_event_text",
    "link_state",
    "pose_text",
    "rounded",
    "speed_text",
    "status_dict",
    "status_line",
    "status_record",
    "status_table",
]


#: Decimals shown of a float field: volts to 0.01; metres, m/s and radians to 0.001
#: (1 mm; 1 mrad is finer than 0.1 degree). The models keep full precision.
DECIMALS = {"power": 2}
#: Decimals of every other float shown.
DEFAULT_DECIMALS = 3


def rounded(name: str, value: float) -> float:
    """``value`` rounded as field ``name`` is shown (DECIMALS)."""
    return round(value, DECIMALS.get(name, DEFAULT_DECIMALS))


def status_dict(status: GalileoStatus) -> dict[str, Any]:
    """A status as plain JSON values: enums as their wire integers, layout as its name.

    Floats are rounded as shown (DECIMALS); ``decode --raw`` and the models keep them all.
    """
    values = status.model_dump(mode="json")
    return {
        key: rounded(key, value) if isinstance(value, float) else value
        for key, value in values.items()
    }


def status_record(status: GalileoStatus | None, link: object | None) -> dict[str, Any]:
    """A JSON status line's ``status`` and ``link`` (null when none yet): the one shape of
    ``status``, ``status --watch``, ``monitor`` and ``fleet status`` (docs/cli.md)."""
    return {
        "status": None if status is None else status_dict(status),
        "link": None if link is None else link_dict(link),
    }


def _value(value: object, name: str = "") -> str:
    if value is None:
        return "—"
    if isinstance(value, enum.IntEnum):
        return f"{value.name.lower()} ({int(value)})"
    if isinstance(value, float):
        return f"{value:.{DECIMALS.get(name, DEFAULT_DECIMALS)}f}"
    return str(value)


def status_table(status: GalileoStatus) -> Table:
    """Every field of a status, one per row (enum fields show name and wire value)."""
    table = Table(show_header=True, header_style="bold", box=None, pad_edge=False)
    table.add_column("field")
    table.add_column("value", justify="right")
    for name in type(status).model_fields:
        table.add_row(name, _value(getattr(status, name), name))
    return table


def pose_text(status: GalileoStatus | None) -> str:
    """The robot's pose to 1 mm and 0.1 degree: ``(+1.234, -0.500) +12.3°``."""
    pose = None if status is None else status.pose
    if pose is None:
        return "pose unknown"
    return f"({pose.x:+.3f}, {pose.y:+.3f}) {pose.degrees:+.1f}°"


def _metres(value: float | None) -> str:
    return "—" if value is None or value < 0 else f"{value:.2f} m"


def speed_text(speed: float | None, form: str = "+.2f") -> str:
    """A speed in m/s (``+0.25 m/s``), or ``speed n/a`` when the link carries none (udp://)."""
    return "speed n/a" if speed is None else f"{speed:{form}} m/s"


def status_line(status: GalileoStatus) -> str:
    """A one-line summary: states, goal, distance, pose and speed."""
    where = pose_text(status)
    goal = "—" if status.target_status is None else status.target_status.name.lower()
    return (
        f"nav {_name(status.nav_status)} · visual {_name(status.visual_status)} · "
        f"target {status.target_num_id} {goal} {_metres(status.target_distance)} · "
        f"{where} · {speed_text(status.current_speed_x)}"
    )


def goal_line(status: GalileoStatus) -> str:
    """A short goal progress line: state, distance to go, speed."""
    goal = "—" if status.target_status is None else status.target_status.name.lower()
    return (
        f"target {status.target_num_id} {goal} · {_metres(status.target_distance)} to go · "
        f"{speed_text(status.current_speed_x, '.2f')}"
    )


def _name(value: enum.IntEnum | None) -> str:
    return "—" if value is None else value.name.lower()


def link_dict(link: object) -> dict[str, Any]:
    """Link statistics (robot.link) as plain values, including last_frame_age."""
    values: dict[str, Any] = {}
    if dataclasses.is_dataclass(link) and not isinstance(link, type):
        for f in dataclasses.fields(link):
            value = getattr(link, f.name)
            if dataclasses.is_dataclass(value) and not isinstance(value, type):
                values.update(dataclasses.asdict(value))  # LinkStats.decoder: its counters
            elif f.repr:
                if f.name == "state":  # LinkStats' flags derived from it come first
                    values.update((key, getattr(link, key)) for key in ("connected", "stale"))
                values[f.name] = value
    age = getattr(link, "last_frame_age", None)
    values["last_frame_age"] = None if age is None else round(float(age), 3)
    for key in ("layout", "state"):  # StatusLayout, LinkState
        value = values.get(key)
        if isinstance(value, enum.Enum):
            values[key] = value.value
    return values


def event_dict(event: object) -> dict[str, Any]:
    """An event as its name (Event.name) and data fields (the status it carries is left out)."""
    name = event.name if isinstance(event, Event) else type(event).__name__
    values: dict[str, Any] = {"event": name}
    if dataclasses.is_dataclass(event) and not isinstance(event, type):
        for item in dataclasses.fields(event):
            if item.name != "status":
                value = getattr(event, item.name)
                if isinstance(value, enum.Enum):
                    value = value.name.lower()
                elif isinstance(value, float):
                    value = rounded(item.name, value)
                values[item.name] = value
    return values


def event_text(event: object) -> str:
    """An event as ``Name key=value …``."""
    values = event_dict(event)
    name = values.pop("event")
    rest = " ".join(f"{key}={_plain(value)}" for key, value in values.items())
    return f"{name} {rest}".strip()


def link_event_text(event: object, *, reconnecting: bool) -> str | None:
    """A line about the link's health for a link event (None for any other event)."""
    if isinstance(event, LinkStaleEvent):
        return f"link stale: no valid status frame for {event.silent_for:.1f} s"
    if isinstance(event, LinkRestored):
        return "link restored: status frames arrive again"
    if isinstance(event, ConnectionLostEvent):
        reason = event.reason
        text = reason if reason.startswith("connection lost") else f"connection lost: {reason}"
        return f"{text}; reconnecting…" if reconnecting else text
    if isinstance(event, ConnectionRestored):
        return "connection restored"
    return None


def _plain(value: object) -> str:
    if isinstance(value, float):
        return "—" if math.isnan(value) else f"{value:.2f}"
    return str(value)


def _grid(rows: Iterable[tuple[str, str]]) -> Table:
    table = Table.grid(padding=(0, 2), expand=True)
    table.add_column(style="dim", no_wrap=True)
    table.add_column(justify="right", no_wrap=True)
    for key, value in rows:
        table.add_row(key, value)
    return table


def dashboard(
    status: GalileoStatus | None,
    link: object,
    events: Iterable[tuple[float, str]],
    *,
    url: str,
) -> RenderableType:
    """The monitor screen: states, pose and speeds, goal, link statistics, recent events."""
    if status is None:
        if getattr(link, "frames", 0):
            # Frames arrive, but only the serial node's placeholders (docs/protocol.md §1).
            return Panel(
                f"{url}: the link is up, but the navigation system has not reported yet …",
                title="galileo monitor",
            )
        return Panel(f"waiting for the first status from {url} …", title="galileo monitor")
    pose = status.pose
    states = _grid(
        [
            ("navigation", _name(status.nav_status)),
            ("visual", _name(status.visual_status)),
            ("map", _name(status.map_status)),
            ("charge", _name(status.charge_status)),
            ("patrol", _flag(status.loop_status, status.patrolling, "on", "off")),
            ("busy", _flag(status.busy_status, status.is_busy, "yes", "no")),
            ("power", "—" if status.power is None else f"{status.power:.2f} V"),
        ]
    )
    motion = _grid(
        [
            ("x", "—" if pose is None else f"{pose.x:+.3f} m"),
            ("y", "—" if pose is None else f"{pose.y:+.3f} m"),
            ("heading", "—" if pose is None else f"{pose.degrees:+.1f}°"),
            ("speed", speed_text(status.current_speed_x).removeprefix("speed ")),
            ("turn rate", _unit(status.current_speed_theta, "rad/s")),
            ("planner speed", _unit(status.control_speed_x, "m/s")),
            ("planner turn", _unit(status.control_speed_theta, "rad/s")),
        ]
    )
    goal = _grid(
        [
            ("target", _value(status.target_num_id)),
            ("state", _name(status.target_status)),
            ("distance", _metres(status.target_distance)),
            ("angle goal", _name(status.angle_goal_status)),
        ]
    )
    link_grid = _grid(_link_rows(link_dict(link)))
    recent = Table.grid()
    for when, text in events:
        recent.add_row(f"[dim]{when:7.1f}s[/] {text}")
    top = Table.grid(padding=(0, 1), expand=True)
    top.add_column(ratio=1)
    top.add_column(ratio=1)
    top.add_row(Panel(states, title="states"), Panel(motion, title="pose & speed"))
    top.add_row(Panel(goal, title="goal"), Panel(link_grid, title="link"))
    title = f"galileo monitor · {url} · layout {status.layout.value} · frame {status.time_stamp}"
    return Panel(Group(top, Panel(recent, title="recent events")), title=title)


#: Link statistics shown by the monitor, with their short labels.
_LINK_ROWS = (
    ("frames", "frames"),
    ("bytes_received", "bytes"),
    ("bytes_discarded", "discarded"),
    ("resyncs", "resyncs"),
    ("lost_frames", "lost"),
    ("reconnects", "reconnects"),
    ("commands_sent", "sent"),
)


#: The colour of each link state, shown by its LinkState name wherever the CLI shows it
#: (the monitor, its small screen, the fleet table).
LINK_STATE_STYLES = {
    LinkState.CONNECTING: "dim", LinkState.UP: "green", LinkState.STALE: "bold yellow",
    LinkState.LOST: "bold red", LinkState.CLOSED: "dim",
}  # fmt: skip


def link_state(stats: dict[str, Any]) -> LinkState:
    """The link state of link_dict's statistics (CONNECTING before any)."""
    return LinkState(stats.get("state") or LinkState.CONNECTING.value)


def _link_rows(stats: dict[str, Any]) -> list[tuple[str, str]]:
    rows = [(label, _value(stats.get(key))) for key, label in _LINK_ROWS]
    state = link_state(stats)
    age = stats.get("last_frame_age")
    rows.append(("link", f"[{LINK_STATE_STYLES[state]}]{state.value}[/]"))
    rows.append(("age", "—" if age is None else f"{age * 1000:.0f} ms"))
    return rows


def _flag(raw: int | None, value: bool, yes: str, no: str) -> str:
    return "—" if raw is None else (yes if value else no)


def _unit(value: float | None, unit: str) -> str:
    return "—" if value is None else f"{value:+.2f} {unit}"
