"""The monitor at any terminal size (80x24 included), its colours and keys: q, m, ?."""

from __future__ import annotations

import asyncio
import contextlib
import enum
import os
import sys
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass

from rich.console import Group, RenderableType
from rich.panel import Panel
from rich.text import Text

from ..models import GalileoStatus
from .map_model import MapModel
from .map_render import map_panel
from .render import LINK_STATE_STYLES, dashboard, link_dict, link_state, speed_text

__all__ = ["FULL_ROWS", "KEYS_HELP", "MonitorView", "keys_pressed", "state_style"]

#: Terminal rows from which the full dashboard and the map are shown one above the other.
FULL_ROWS = 50
#: The footer line of the monitor.
KEYS_HELP = "q quit · m map on/off · ? help"
_HELP = (
    "keys\n"
    "  q   quit (Ctrl-C too)\n"
    "  m   show or hide the map (hidden: more events)\n"
    "  ?   show or hide this help\n\n"
    "colours: green = working as it should, cyan = moving to a goal,\n"
    "yellow = waiting or paused, red = an error or the visual system lost,\n"
    "dim = off or not known"
)
#: Styles of state names, whatever enum they belong to (names are the enums' own).
_STYLES = {
    "OPEN": "green", "TRACKING": "green", "FREE": "green", "CHARGING": "green",
    "CHARGED": "green", "DONE": "green", "MAPPING": "cyan", "WORKING": "cyan",
    "DOCKING": "cyan", "FINDING_DOCK": "cyan", "NOT_INITIALISED": "yellow",
    "PAUSED": "yellow", "NOT_DONE": "yellow", "LOST": "bold red", "ERROR": "bold red",
    "CLOSED": "dim", "OFF": "dim", "IDLE": "dim", "INVALID": "dim",
}  # fmt: skip


def state_style(value: enum.IntEnum | None) -> str:
    """The colour of a state by its own enum's name (dim when unknown)."""
    return "dim" if value is None else _STYLES.get(value.name, "")


@dataclass
class MonitorView:
    """What the monitor shows: toggled by keys; ``quit`` once q was pressed."""

    show_map: bool = True
    show_help: bool = False
    quit: bool = False

    def press(self, key: str) -> None:
        """Apply one key (others are ignored)."""
        if key in ("q", "Q"):
            self.quit = True
        elif key in ("m", "M"):
            self.show_map = not self.show_map
        elif key == "?":
            self.show_help = not self.show_help

    def screen(
        self,
        status: GalileoStatus | None,
        link: object,
        events: list[tuple[float, str]],
        *,
        url: str,
        model: MapModel,
        rows: int,
    ) -> RenderableType:
        """The screen for a terminal of ``rows`` rows: full above FULL_ROWS, else compact."""
        footer = Text(KEYS_HELP, style="dim")
        if self.show_help:
            return Group(Panel(_HELP, title="galileo monitor · help"), footer)
        if rows >= FULL_ROWS:
            board = dashboard(status, link, events, url=url)
            parts: list[RenderableType] = [board]
            if self.show_map:
                parts.append(map_panel(model))
            return Group(*parts, footer)
        head = _compact(status, link, url)
        used = len(head) + 1  # the footer
        if self.show_map:
            shown = events[-2:]
            map_rows = rows - used - len(shown) - 2 - 1  # panel borders; one spare row
            if map_rows >= 4:
                return Group(*head, *_event_lines(shown), map_panel(model, map_rows), footer)
        shown = events[-max(0, rows - used - 1) :]
        return Group(*head, *_event_lines(shown), footer)


def _event_lines(events: Iterable[tuple[float, str]]) -> list[Text]:
    return [
        Text(f"{when:7.1f}s {text}", overflow="ellipsis", no_wrap=True) for when, text in events
    ]


#: One shown value of a compact line: (label, value, style of the value).
_Pair = tuple[str, str, str]


def _line(pairs: Iterable[_Pair]) -> Text:
    """``label value`` pairs two spaces apart; cut with an ellipsis only past the screen."""
    line = Text(no_wrap=True, overflow="ellipsis")
    for index, (label, value, style) in enumerate(pairs):
        if index:
            line.append("  ")
        line.append(f"{label} ", style="dim")
        line.append(value, style=style)
    return line


def _named(label: str, value: enum.IntEnum | None) -> _Pair:
    return (label, "—" if value is None else value.name.lower(), state_style(value))


def _compact(status: GalileoStatus | None, link: object, url: str) -> list[Text]:
    """A title line and three coloured lines (states; pose and speed; goal, power and link)
    that fit 80 columns with the longest value of each (tests/cli/test_cli_monitor_small.py)."""
    stats = link_dict(link)
    title = Text("galileo monitor", style="bold", overflow="ellipsis", no_wrap=True)
    if status is None:
        title.append(f" · {url}")
        waiting = "the link is up, waiting for the navigation system …"
        return [title, Text(waiting if stats.get("frames") else "waiting for the first status …")]
    # The URL last: a long one is what the ellipsis cuts, never the layout or the frame.
    title.append(f" · {status.layout.value} · frame {status.time_stamp} · ", style="dim")
    title.append(url)
    states = [
        _named("nav", status.nav_status), _named("visual", status.visual_status),
        _named("map", status.map_status), _named("charge", status.charge_status),
    ]  # fmt: skip
    if status.loop_status is not None:
        states.append(("patrol", *(("on", "cyan") if status.patrolling else ("off", "dim"))))
    motion: list[_Pair] = []
    pose = status.pose
    if pose is not None:
        motion += [
            ("x", f"{pose.x:+.2f}", ""), ("y", f"{pose.y:+.2f} m", ""),
            ("heading", f"{pose.degrees:+.1f}°", ""),
        ]  # fmt: skip
    # udp:// frames carry no speed: unknown, never 0.
    motion.append(("speed", speed_text(status.current_speed_x).removeprefix("speed "), ""))
    if status.current_speed_theta is not None:
        motion.append(("turn", f"{status.current_speed_theta:+.2f} rad/s", ""))
    target, distance = status.target_status, status.target_distance
    state = link_state(stats)
    goal = [
        ("goal", "—" if status.target_num_id is None else str(status.target_num_id), ""),
        _named("state", target),
        ("distance", "—" if distance is None or distance < 0 else f"{distance:.2f} m", ""),
    ]
    if status.power is not None:
        goal.append(("power", f"{status.power:.1f} V", ""))
    goal.append(("link", state.value, LINK_STATE_STYLES[state]))
    return [title, _line(states), _line(motion), _line(goal)]


@contextlib.contextmanager
def keys_pressed(on_key: Callable[[str], None]) -> Iterator[bool]:
    """Call ``on_key`` for each key typed on a terminal stdin (no echo); yield whether one is.

    Without a terminal (a pipe, a test) nothing is read: yields False.
    """
    if not sys.stdin.isatty():
        yield False
        return
    import termios
    import tty

    fd = sys.stdin.fileno()
    saved = termios.tcgetattr(fd)
    loop = asyncio.get_running_loop()

    def readable() -> None:
        data = os.read(fd, 64).decode(errors="ignore")
        for key in data:
            on_key(key)

    tty.setcbreak(fd)  # keys one at a time, not echoed over the screen; Ctrl-C still works
    loop.add_reader(fd, readable)
    try:
        yield True
    finally:
        loop.remove_reader(fd)
        termios.tcsetattr(fd, termios.TCSADRAIN, saved)
