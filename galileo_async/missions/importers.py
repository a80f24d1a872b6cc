"""Plans in other formats as missions: the vendor's timeTask.json and Nav2's waypoint files.

timeTask.json is what the vendor's scheduler (system_monitor's time_tasks.py) runs:
``mapSwithTasks`` (switch map and path at a time) and ``autoRunTasks`` (switch map and
path, then loop over every point of the path, waiting ``waitTime`` s at each, ``loopCount``
times (0: until the window closes), then go to ``stopPose``: -1 the dock, else a point's
index). ``whichDay`` is 0 for every day, 1-7 for Monday-Sunday; ``startTime`` and
``stopTime`` are "HH:MM". A path's points are the map's targets in file order (the
robot's ``nav_<path>.csv``, or ``new_nav_<path>.csv`` with headings), so a point's index
is its target id: the import visits them with ``goto`` (every link), or with
``goto_pose`` (http://) when asked for poses.

Nav2's waypoint files: the RViz Nav2 panel's ``waypoints: {waypoint0: {pose: [x, y, z],
orientation: [w, x, y, z]}, …}``, or a list of poses (``position`` and ``orientation``
mappings, as geometry_msgs writes them, optionally under ``pose:``).
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

from .files import FileProblem, MissionFileError, load_mission, yaml_module
from .model import Mission

__all__ = [
    "FORMATS",
    "ImportedPlan",
    "ImportedWindow",
    "PlanFormat",
    "PointSource",
    "Waypoint",
    "as_points",
    "detect_format",
    "import_nav2",
    "import_timetask",
    "load_plan",
    "parse_nav_points",
    "points_from_folder",
    "read_nav_points",
]

#: The formats a plan file can be in: ours, the vendor's timeTask.json, Nav2's waypoints.
PlanFormat = Literal["mission", "timetask", "nav2"]
FORMATS: tuple[PlanFormat, ...] = ("mission", "timetask", "nav2")


@dataclass(frozen=True)
class Waypoint:
    """A point of a path: metres and radians (theta 0 where the file has no heading)."""

    x: float
    y: float
    theta: float = 0.0


#: Where an import finds the points of a map's path: a function of (map, path), or one
#: list of points for every path.
PointSource = Callable[[str, str], Sequence[Waypoint]] | Sequence[Waypoint]


@dataclass(frozen=True)
class ImportedWindow:
    """A time window of an imported schedule: ISO weekdays (1 Monday … 7 Sunday), "HH:MM"."""

    days: tuple[int, ...]
    start: str
    stop: str
    mission: Mission
    #: The vendor's task list it came from: "autoRunTasks" or "mapSwithTasks".
    kind: str = "autoRunTasks"
    #: The vendor's stopPose: -1 the dock, else a point's index (None: a mapSwithTask).
    stop_pose: int | None = None

    def as_dict(self) -> dict[str, Any]:
        """Plain data: {days, start, stop, mission} (the mission as its model dump)."""
        return {
            "days": list(self.days),
            "start": self.start,
            "stop": self.stop,
            "mission": self.mission.model_dump(mode="json", by_alias=True, exclude_defaults=True),
        }


@dataclass(frozen=True)
class ImportedPlan:
    """What an import made: the missions, the schedule's windows, and notes for the user."""

    missions: list[Mission]
    windows: list[ImportedWindow] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)


def read_nav_points(path: str | Path) -> list[Waypoint]:
    """The points of a vendor nav_points file: ``nav.csv`` lines "x y z", ``new_nav.csv``
    lines "x y z theta …" (space separated; the robot's map folder keeps them per path)."""
    source = str(path)
    text = Path(path).read_text(encoding="utf-8")
    return parse_nav_points(text, source=source)


def parse_nav_points(text: str, *, source: str = "<points>") -> list[Waypoint]:
    """Points from nav_points text (see read_nav_points); MissionFileError names bad lines."""
    points: list[Waypoint] = []
    problems: list[FileProblem] = []
    for number, line in enumerate(text.splitlines(), start=1):
        fields = line.split()
        if not fields:
            continue
        try:
            values = [float(value) for value in fields[:4]]
        except ValueError:
            values = []
        if len(values) < 2 or not all(math.isfinite(value) for value in values):
            message = f"not a point: {line.strip()!r} (expected 'x y z' or 'x y z theta …')"
            problems.append(FileProblem(source, number, None, None, message))
            continue
        theta = values[3] if len(values) >= 4 else 0.0
        points.append(Waypoint(values[0], values[1], theta))
    if problems:
        raise MissionFileError(problems)
    return points


def points_from_folder(folder: str | Path) -> Callable[[str, str], list[Waypoint]]:
    """A PointSource reading the vendor's maps folder: ``FOLDER/<map>/new_nav_<path>.csv``,
    else ``FOLDER/<map>/nav_<path>.csv`` (as time_tasks.py switches maps)."""
    root = Path(folder)

    def points(map_name: str, path_name: str) -> list[Waypoint]:
        for name in (f"new_nav_{path_name}.csv", f"nav_{path_name}.csv"):
            candidate = root / map_name / name
            if candidate.is_file():
                return read_nav_points(candidate)
        raise FileNotFoundError(
            f"no nav_{path_name}.csv or new_nav_{path_name}.csv in {root / map_name}"
        )

    return points


_HH_MM = re.compile(r"^([01]?\d|2[0-3]):([0-5]\d)$")


def import_timetask(
    text: str,
    points: PointSource,
    *,
    source: str = "timeTask.json",
    poses: bool = False,
) -> ImportedPlan:
    """The missions and windows of a timeTask.json; ``points`` gives each path's points.

    An autoRunTask becomes: switch_map {map, path}; a loop (``loopCount`` times, 0: until
    stopped) of goto i and dwell ``waitTime`` s over the path's points (goto_pose with
    ``poses``); then charge (stopPose -1) or goto stopPose. A mapSwithTask becomes a
    switch_map alone. MissionFileError names every entry that cannot be read.
    """
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        problem = FileProblem(source, exc.lineno, None, None, f"JSON: {exc.msg}")
        raise MissionFileError([problem]) from None
    if not isinstance(data, dict) or not ({"autoRunTasks", "mapSwithTasks"} & set(data)):
        message = "not a timeTask.json: no autoRunTasks or mapSwithTasks"
        raise MissionFileError([FileProblem(source, None, None, None, message)])
    plan = ImportedPlan(missions=[])
    problems: list[FileProblem] = []
    for kind in ("mapSwithTasks", "autoRunTasks"):
        tasks = data.get(kind) or []
        if not isinstance(tasks, list):
            problems.append(FileProblem(source, None, kind, None, "not a list"))
            continue
        for index, task in enumerate(tasks):
            where = f"{kind}[{index}]"
            try:
                window = _window(kind, index, task, points, poses, plan.notes)
            except (KeyError, TypeError, ValueError, OSError) as exc:
                problems.append(FileProblem(source, None, where, None, _reason(exc)))
                continue
            plan.missions.append(window.mission)
            plan.windows.append(window)
    if problems:
        raise MissionFileError(problems)
    return plan


def _reason(exc: BaseException) -> str:
    if isinstance(exc, KeyError):
        return f"missing key {exc.args[0]!r}"
    if isinstance(exc, MissionFileError):
        return "; ".join(exc.problems)
    return str(exc)


def _window(
    kind: str, index: int, task: Any, points: PointSource, poses: bool, notes: list[str]
) -> ImportedWindow:
    if not isinstance(task, dict):
        raise TypeError(f"a task is a JSON object, not {task!r}")
    day = task["whichDay"]
    if not isinstance(day, int) or not 0 <= day <= 7:
        raise ValueError(f"whichDay {day!r} is not 0 (every day) or 1-7 (Monday-Sunday)")
    start, stop = _hh_mm(task["startTime"], "startTime"), _hh_mm(task["stopTime"], "stopTime")
    map_name, path_name = str(task["mapName"]), str(task["pathName"])
    label = f"{kind}[{index}] {map_name}/{path_name} {start}-{stop}"
    steps: list[dict[str, Any]] = [
        {"switch_map": {"map": map_name, "path": path_name}, "name": "switch map"}
    ]
    if kind == "autoRunTasks":
        steps += _patrol(task, map_name, path_name, points, poses, label, notes)
    mission = Mission.model_validate({"mission": label, "steps": steps})
    days = tuple(range(1, 8)) if day == 0 else (day,)
    stop_pose = int(task["stopPose"]) if kind == "autoRunTasks" else None
    return ImportedWindow(days, start, stop, mission, kind, stop_pose)


def _hh_mm(value: Any, key: str) -> str:
    match = _HH_MM.match(str(value))
    if match is None:
        raise ValueError(f"{key} {value!r} is not HH:MM")
    return f"{int(match[1]):02d}:{match[2]}"


def _patrol(
    task: dict[str, Any],
    map_name: str,
    path_name: str,
    points: PointSource,
    poses: bool,
    label: str,
    notes: list[str],
) -> list[dict[str, Any]]:
    wait, stop_pose, loops = float(task["waitTime"]), int(task["stopPose"]), int(task["loopCount"])
    if wait < 0 or loops < 0:
        raise ValueError("waitTime and loopCount must not be negative")
    path = list(points(map_name, path_name) if callable(points) else points)
    if not path:
        raise ValueError(f"the path {map_name}/{path_name} has no points")
    body: list[dict[str, Any]] = []
    for number, point in enumerate(path):
        body.append(_visit(number, point, poses))
        if wait > 0:
            body.append({"dwell": wait})
    loop: dict[str, Any] = {"steps": body} if loops == 0 else {"count": loops, "steps": body}
    steps: list[dict[str, Any]] = [{"loop": loop, "name": "patrol"}]
    if stop_pose < 0:
        steps.append({"charge": {}, "name": "stop pose"})
    elif stop_pose < len(path):
        steps.append({**_visit(stop_pose, path[stop_pose], poses), "name": "stop pose"})
    else:
        notes.append(
            f"{label}: stopPose {stop_pose} is past the path's {len(path)} points; the "
            "vendor's scheduler skips it, and so does this mission"
        )
    return steps


def _visit(number: int, point: Waypoint, poses: bool) -> dict[str, Any]:
    if poses:
        return {"goto_pose": {"x": point.x, "y": point.y, "theta": point.theta}}
    return {"goto": number}


def import_nav2(
    text: str,
    *,
    source: str = "waypoints.yaml",
    name: str | None = None,
    headings: bool = True,
    loops: int | None = None,
) -> Mission:
    """A mission from a Nav2 waypoint file: goto_pose per waypoint (http://), goto_point
    without ``headings``; ``loops`` as Nav2's number_of_loops (N: N + 1 passes), else the
    file's ``number_of_loops`` key, else one pass."""
    yaml = yaml_module()
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        line = None if mark is None else mark.line + 1
        raise MissionFileError([FileProblem(source, line, None, None, f"YAML: {exc}")]) from None
    if not isinstance(data, dict) or "waypoints" not in data:
        message = "not a Nav2 waypoint file: no `waypoints:`"
        raise MissionFileError([FileProblem(source, None, None, None, message)])
    problems: list[FileProblem] = []
    waypoints = _nav2_waypoints(data["waypoints"], source, problems)
    if loops is None:
        loops = data.get("number_of_loops", 0)
    if not isinstance(loops, int) or isinstance(loops, bool) or loops < 0:
        problems.append(FileProblem(source, None, None, None, f"number_of_loops {loops!r}"))
    if not waypoints and not problems:
        problems.append(FileProblem(source, None, None, None, "no waypoints"))
    if problems:
        raise MissionFileError(problems)
    steps: list[dict[str, Any]] = []
    for label, point in waypoints:
        if headings:
            step: dict[str, Any] = {"goto_pose": {"x": point.x, "y": point.y, "theta": point.theta}}
        else:
            step = {"goto_point": {"x": point.x, "y": point.y}}
        steps.append({**step, "name": label})
    if loops:
        steps = [{"loop": {"count": int(loops) + 1, "steps": steps}}]
    title = name or Path(source).stem or "waypoints"
    return Mission.model_validate({"mission": title, "steps": steps})


def _nav2_waypoints(
    value: Any, source: str, problems: list[FileProblem]
) -> list[tuple[str, Waypoint]]:
    items: list[tuple[str, Any]]
    if isinstance(value, dict):
        items = [(str(key), item) for key, item in value.items()]
    elif isinstance(value, list):
        items = [(f"waypoint{index}", item) for index, item in enumerate(value)]
    else:
        problems.append(FileProblem(source, None, "waypoints", None, "not a mapping or a list"))
        return []
    found: list[tuple[str, Waypoint]] = []
    for label, item in items:
        try:
            found.append((label, _nav2_pose(item)))
        except (KeyError, TypeError, ValueError, IndexError) as exc:
            problems.append(FileProblem(source, None, f"waypoints.{label}", None, _reason(exc)))
    return found


def _nav2_pose(item: Any) -> Waypoint:
    """A waypoint: the panel's {pose: [x, y, z], orientation: [w, x, y, z]}, or a Pose."""
    if not isinstance(item, dict):
        raise TypeError(f"a waypoint is a mapping, not {item!r}")
    pose = item.get("pose", item)
    if isinstance(pose, list):  # the RViz Nav2 panel: orientation is [w, x, y, z]
        w, qx, qy, qz = (float(v) for v in item.get("orientation", [1.0, 0.0, 0.0, 0.0]))
        x, y = float(pose[0]), float(pose[1])
    else:  # geometry_msgs/Pose (or PoseStamped's pose): named fields
        position, orientation = pose["position"], pose.get("orientation") or {"w": 1.0}
        x, y = float(position["x"]), float(position["y"])
        qx, qy = float(orientation.get("x", 0.0)), float(orientation.get("y", 0.0))
        qz, w = float(orientation.get("z", 0.0)), float(orientation.get("w", 1.0))
    if not all(math.isfinite(v) for v in (x, y, w, qx, qy, qz)):
        raise ValueError("a waypoint's numbers must be finite")
    theta = math.atan2(2.0 * (w * qz + qx * qy), 1.0 - 2.0 * (qy * qy + qz * qz))
    return Waypoint(x, y, round(theta, 6))


def detect_format(path: str | Path, text: str | None = None) -> PlanFormat:
    """The format of a plan file: timeTask.json by its keys, Nav2 by ``waypoints:``, else ours."""
    text = Path(path).read_text(encoding="utf-8") if text is None else text
    if Path(path).suffix.lower() == ".json" or text.lstrip().startswith("{"):
        try:
            data = json.loads(text)
        except json.JSONDecodeError:
            data = None
        if isinstance(data, dict) and {"autoRunTasks", "mapSwithTasks"} & set(data):
            return "timetask"
    if re.search(r"^waypoints\s*:", text, flags=re.MULTILINE) and not re.search(
        r"^steps\s*:", text, flags=re.MULTILINE
    ):
        return "nav2"
    return "mission"


def load_plan(
    path: str | Path,
    *,
    plan_format: PlanFormat | None = None,
    points: PointSource | None = None,
    poses: bool = False,
    headings: bool = True,
    loops: int | None = None,
) -> ImportedPlan:
    """Any plan file as an ImportedPlan (``plan_format`` None: detect_format); a mission
    file or a Nav2 file gives one mission and no windows. ``points`` and ``poses`` are
    import_timetask's, ``headings`` and ``loops`` import_nav2's."""
    path = Path(path)
    text = path.read_text(encoding="utf-8")
    kind = plan_format or detect_format(path, text)
    if kind == "timetask":
        if points is None:
            message = (
                "a timeTask.json needs the points of its paths: --points FILE (a nav_points "
                "file), --points DIR (the robot's maps folder) or a robot on http:// (-p URL)"
            )
            raise MissionFileError([FileProblem(str(path), None, None, None, message)])
        return import_timetask(text, points, source=str(path), poses=poses)
    if kind == "nav2":
        return ImportedPlan([import_nav2(text, source=str(path), headings=headings, loops=loops)])
    return ImportedPlan([load_mission(path)])


def as_points(values: Sequence[Any]) -> list[Waypoint]:
    """Waypoints from objects with x, y and theta (robot.http.targets()'s NavPoint)."""
    return [Waypoint(float(v.x), float(v.y), float(getattr(v, "theta", 0.0))) for v in values]
