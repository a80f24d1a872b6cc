"""What the map panel shows, without drawing it: robots, fading trails, known targets, bounds."""

from __future__ import annotations

import csv
import math
import time
from collections import deque
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path

from ..errors import InvalidArgument
from ..models import GalileoStatus, TargetStatus
from ..transitions import DEFAULT_ARRIVE_TOLERANCE, GoalChange, GoalMachine

__all__ = [
    "MIN_SPAN",
    "TRAIL_SECONDS",
    "Bounds",
    "MapModel",
    "MapTarget",
    "RobotTrack",
    "known_targets",
    "load_targets_csv",
]

#: Seconds of trail kept behind each robot.
TRAIL_SECONDS = 60.0
#: Metres a robot moves before its trail gets another point (a standing robot adds none).
TRAIL_STEP = 0.05
#: Smallest width and height of the map, metres (a lone robot is not one huge dot).
MIN_SPAN = 4.0
#: Where a target's position came from, in the order one source overrides another.
SOURCES = ("learned", "map", "dynamic", "file")


@dataclass(frozen=True)
class MapTarget:
    """A target whose position is known: goal id, metres in the map frame, and from where."""

    target_id: int
    x: float
    y: float
    source: str


@dataclass
class RobotTrack:
    """One robot on the map: its latest pose and goal, and its trail of (time, x, y)."""

    name: str
    x: float = 0.0
    y: float = 0.0
    theta: float = 0.0
    goal: int | None = None
    trail: deque[tuple[float, float, float]] = field(default_factory=deque)


@dataclass(frozen=True)
class Bounds:
    """The map frame's rectangle to show, metres."""

    x_min: float
    x_max: float
    y_min: float
    y_max: float

    @property
    def width(self) -> float:
        """Metres across."""
        return self.x_max - self.x_min

    @property
    def height(self) -> float:
        """Metres from bottom to top."""
        return self.y_max - self.y_min


class MapModel:
    """Robots, trails and targets of a map view; fed statuses, asked for what to draw."""

    def __init__(
        self,
        *,
        trail_seconds: float = TRAIL_SECONDS,
        clock: Callable[[], float] = time.monotonic,
        arrive_tolerance: float = DEFAULT_ARRIVE_TOLERANCE,
    ) -> None:
        self.trail_seconds = trail_seconds
        self.clock = clock
        self.arrive_tolerance = arrive_tolerance
        self._machines: dict[str, GoalMachine] = {}  # each robot's goals, as events() sees them
        self.robots: dict[str, RobotTrack] = {}
        self.targets: dict[int, MapTarget] = {}

    def add_target(self, target_id: int, x: float, y: float, source: str = "dynamic") -> None:
        """Know target ``target_id`` at (x, y); a source later in SOURCES wins over an earlier."""
        if source not in SOURCES:
            raise InvalidArgument(f"source must be one of {', '.join(SOURCES)}, got {source!r}")
        known = self.targets.get(target_id)
        if known is None or SOURCES.index(source) >= SOURCES.index(known.source):
            self.targets[target_id] = MapTarget(target_id, float(x), float(y), source)

    def add_targets(self, targets: Iterable[tuple[int, float, float]], source: str) -> None:
        """Know each (id, x, y) of ``targets``."""
        for target_id, x, y in targets:
            self.add_target(target_id, x, y, source)

    def update(self, name: str, status: GalileoStatus, now: float | None = None) -> None:
        """Move robot ``name`` to the status's pose; learn a target it is seen to arrive at.

        Arrived means what goto() and events() mean (one transitions.GoalMachine per robot):
        a goal that ends free within ``arrive_tolerance``.
        """
        machine = self._machines.get(name)
        if machine is None:
            machine = self._machines[name] = GoalMachine(arrive_tolerance=self.arrive_tolerance)
        step = machine.step(status)
        pose = status.pose
        if pose is None:
            return
        x, y = pose.x, pose.y
        now = self.clock() if now is None else now
        track = self.robots.get(name)
        if track is None:
            track = self.robots[name] = RobotTrack(name)
        track.x, track.y = x, y
        track.theta = pose.theta
        trail = track.trail
        if not trail or math.hypot(x - trail[-1][1], y - trail[-1][2]) >= TRAIL_STEP:
            trail.append((now, x, y))
        while trail and now - trail[0][0] > self.trail_seconds:
            trail.popleft()
        goal = status.target_num_id
        working = status.target_status in (TargetStatus.WORKING, TargetStatus.PAUSED)
        track.goal = goal if goal is not None and goal >= 0 and working else None
        for change, target_id in step.changes:
            if change is GoalChange.REACHED and target_id is not None and target_id >= 0:
                self.add_target(target_id, x, y, "learned")

    def forget(self, name: str) -> None:
        """Take robot ``name`` off the map."""
        self.robots.pop(name, None)
        self._machines.pop(name, None)

    def goals(self) -> set[int]:
        """Target ids some robot is driving to (or paused on the way to)."""
        return {track.goal for track in self.robots.values() if track.goal is not None}

    def bounds(self, margin: float = 0.1) -> Bounds:
        """A rectangle around every robot, trail point and target, ``margin`` of it added."""
        xs: list[float] = []
        ys: list[float] = []
        for track in self.robots.values():
            xs.append(track.x)
            ys.append(track.y)
            xs.extend(point[1] for point in track.trail)
            ys.extend(point[2] for point in track.trail)
        xs.extend(target.x for target in self.targets.values())
        ys.extend(target.y for target in self.targets.values())
        if not xs:
            return Bounds(-MIN_SPAN / 2, MIN_SPAN / 2, -MIN_SPAN / 2, MIN_SPAN / 2)
        return Bounds(*_span(min(xs), max(xs), margin), *_span(min(ys), max(ys), margin))


def _span(low: float, high: float, margin: float) -> tuple[float, float]:
    middle, half = (low + high) / 2, max(high - low, MIN_SPAN) * (0.5 + margin)
    return middle - half, middle + half


def load_targets_csv(path: str | Path) -> list[tuple[int, float, float]]:
    """Read ``id,x,y`` rows (a header row is allowed); InvalidArgument naming the bad line."""
    file = Path(path)
    try:
        text = file.read_text(encoding="utf-8")
    except OSError as exc:
        raise InvalidArgument(f"{file}: cannot read the targets file: {exc.strerror}") from None
    targets: list[tuple[int, float, float]] = []
    for number, row in enumerate(csv.reader(text.splitlines()), start=1):
        cells = [cell.strip() for cell in row]
        if not cells or not any(cells) or cells[0].startswith("#"):
            continue
        if number == 1 and cells[0].lower() == "id":
            continue  # the header
        try:
            if len(cells) != 3:
                raise ValueError("expected 3 columns: id,x,y")
            target_id, x, y = int(cells[0]), float(cells[1]), float(cells[2])
            if not 0 <= target_id <= 255 or not (math.isfinite(x) and math.isfinite(y)):
                raise ValueError("id must be 0..255 and x, y finite metres")
        except ValueError as exc:
            raise InvalidArgument(f"{file}:{number}: {exc} (got {row!r})") from None
        targets.append((target_id, x, y))
    return targets


def known_targets(urls: Iterable[str], targets_file: Path | None) -> MapModel:
    """A MapModel knowing the simulator's map of any ``sim://`` URL and a targets file's."""
    from ..sim import parse_sim_url

    model = MapModel()
    for url in urls:
        if url.startswith("sim:"):
            targets = parse_sim_url(url).targets
            model.add_targets(((i, x, y) for i, (x, y) in enumerate(targets)), "map")
    if targets_file is not None:
        model.add_targets(load_targets_csv(targets_file), "file")
    return model
