"""``galileo mission``: the mission file's schema, imports of other plan formats, checks.

Mission files need PyYAML (the extra ``[missions]``); without it each command says how to
install it and exits 1. ``check`` exits 0, or 2 naming every problem (docs/missions.md).
"""

from __future__ import annotations

import json
from collections.abc import Awaitable, Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, NoReturn

import typer

from ..links import link_kind, url_forms
from .runner import ExitCode, Settings, fail, out_console, print_json, run_robot, settings_of

if TYPE_CHECKING:
    from ..missions.check import Problem, WindowCheck
    from ..missions.importers import ImportedPlan, PlanFormat, PointSource
    from ..robot import Robot

__all__ = [
    "INSTALL_HINT",
    "FormatOption",
    "PointsOption",
    "file_failure",
    "load_plan_file",
    "load_plan_from_robot",
    "mission_app",
    "plan_errors",
    "plan_format_of",
    "point_source",
    "robot_points",
]

#: How to get what `galileo mission` needs besides the command line.
INSTALL_HINT = "pip install 'galileo-async[cli,missions]'"

mission_app = typer.Typer(
    help="Mission files: print their JSON Schema, import other plan formats, check a plan.",
    no_args_is_help=True,
)

FormatOption = Annotated[
    str,
    typer.Option(
        "--format",
        help="The plan file's format: auto (by its content), mission, timetask (the "
        "vendor's timeTask.json) or nav2 (Nav2 waypoints).",
    ),
]
PointsOption = Annotated[
    Path | None,
    typer.Option(
        "--points",
        help="timeTask.json: the points of its paths, a nav_points file (nav_<path>.csv, "
        "new_nav_<path>.csv) for every path, or the robot's maps folder (MAP/nav_PATH.csv).",
    ),
]
PortOption = Annotated[
    str | None,
    typer.Option(
        "--port",
        "-p",
        metavar="URL",
        # Built at import, as galileo --port's: plugins' schemes are not loaded for it.
        help=f"The robot to read from and check against: {url_forms(plugins=False)}.",
    ),
]
#: The points of a map's path, read from a robot: (map, path) -> waypoints.
RobotPoints = Callable[[str, str], Awaitable[list[Any]]]
JsonFlag = Annotated[bool, typer.Option("--json", help="Print the result as JSON.")]


@contextmanager
def plan_errors() -> Iterator[None]:
    """A missing PyYAML or an unreadable file as one error line (exit 1)."""
    try:
        yield
    except ModuleNotFoundError as exc:
        if exc.name != "yaml":
            raise
        fail(f"galileo mission needs PyYAML (yaml is not installed): {INSTALL_HINT}")
    except OSError as exc:
        fail(f"cannot read {getattr(exc, 'filename', None) or 'the file'}: {exc.strerror or exc}")


@mission_app.command("schema")
def schema() -> None:
    """Print the JSON Schema of mission files (also docs/mission.schema.json)."""
    from ..missions.files import mission_schema

    out_console().print(json.dumps(mission_schema(), indent=2), markup=False)


def plan_format_of(value: str) -> PlanFormat | None:
    """The --format value as a PlanFormat (None: auto); BadParameter for another."""
    from ..missions.importers import FORMATS

    if value == "auto":
        return None
    if value not in FORMATS:
        raise typer.BadParameter(
            f"{value!r} is not one of auto, {', '.join(FORMATS)}", param_hint="--format"
        )
    return value


def point_source(points: Path | None) -> PointSource | None:
    """The --points file or folder as a PointSource (None: none given)."""
    from ..missions.importers import points_from_folder, read_nav_points

    if points is None:
        return None
    if points.is_dir():
        return points_from_folder(points)
    return read_nav_points(points)


def robot_points(robot: Robot) -> RobotPoints | None:
    """The points of a map's path as ``robot`` reads them (None: its link has no HTTP API)."""
    http = robot.http
    if http is None:
        return None

    async def source(map_name: str, path_name: str) -> list[Any]:
        from ..missions.importers import as_points

        return as_points(await http.targets(map_name, path_name))

    return source


def _port(settings: Settings, port: str | None) -> bool:
    """Apply a command's own --port; True when a robot was named (not the default sim)."""
    if port is not None:
        settings.port, settings.port_source = port, "--port"
    return settings.port_source != "default"


@mission_app.command("import")
def import_plan(
    ctx: typer.Context,
    file: Annotated[Path, typer.Argument(help="timeTask.json, a Nav2 waypoint file, …")],
    plan_format: FormatOption = "auto",
    points: PointsOption = None,
    poses: Annotated[
        bool, typer.Option("--poses", help="timeTask.json: goto_pose (http://), not goto ID.")
    ] = False,
    headings: Annotated[
        bool,
        typer.Option(
            "--headings/--no-headings",
            help="Nav2: goto_pose with each waypoint's heading (http://), or goto_point.",
        ),
    ] = True,
    loops: Annotated[
        int | None,
        typer.Option("--loops", min=0, help="Nav2: number_of_loops (N: N + 1 passes)."),
    ] = None,
    as_schedule: Annotated[
        bool,
        typer.Option("--schedule", help="timeTask.json: print one schedule file, missions inline."),
    ] = False,
    port: PortOption = None,
    json_output: JsonFlag = False,
) -> None:
    """Print a plan of another format as mission YAML (a timeTask.json: one per window,
    or with --schedule one schedule file)."""
    settings = settings_of(ctx)
    settings.json = settings.json or json_output
    kind = plan_format_of(plan_format)
    from_robot = _port(settings, port) and points is None
    if from_robot and link_kind(settings.port) != "http":
        fail("the points of a timeTask.json's paths come from --points or an http:// robot")
    if not from_robot:
        with plan_errors():
            plan = load_plan_file(
                settings, file, kind, point_source(points), poses, headings, loops
            )
        _print_plan(settings, plan, file if as_schedule else None)
        raise typer.Exit(int(ExitCode.OK))

    async def body(robot: Robot) -> int:
        source = robot_points(robot)
        assert source is not None  # an http:// link has its REST part
        plan = await load_plan_from_robot(settings, file, kind, source, poses, headings, loops)
        _print_plan(settings, plan, file if as_schedule else None)
        return int(ExitCode.OK)

    run_robot(settings, body)


def load_plan_file(
    settings: Settings,
    file: Path,
    kind: PlanFormat | None,
    points: PointSource | None,
    poses: bool,
    headings: bool,
    loops: int | None,
) -> ImportedPlan:
    """load_plan on ``file``; a file that does not load prints every problem, exit 2."""
    from ..missions.files import MissionFileError
    from ..missions.importers import load_plan

    try:
        return load_plan(
            file, plan_format=kind, points=points, poses=poses, headings=headings, loops=loops
        )
    except MissionFileError as exc:
        file_failure(settings, exc)


async def load_plan_from_robot(
    settings: Settings,
    file: Path,
    kind: PlanFormat | None,
    source: RobotPoints,
    poses: bool,
    headings: bool,
    loops: int | None,
) -> ImportedPlan:
    """load_plan with each path's points read from the robot first (the import is sync)."""
    from ..missions.importers import detect_format

    with plan_errors():
        text = _read(file)
        if (kind or detect_format(file, text)) != "timetask":
            return load_plan_file(settings, file, kind, None, poses, headings, loops)
    cache = await _robot_points(text, source)
    return load_plan_file(
        settings, file, "timetask", lambda m, p: cache[(m, p)], poses, headings, loops
    )


def _read(file: Path) -> str:
    return file.read_text(encoding="utf-8")


async def _robot_points(text: str, source: RobotPoints) -> dict[tuple[str, str], list[Any]]:
    cache: dict[tuple[str, str], list[Any]] = {}
    try:
        tasks = json.loads(text).get("autoRunTasks") or []
    except (json.JSONDecodeError, AttributeError):
        return cache  # the import names what is wrong with the file
    for task in tasks:
        if isinstance(task, dict) and "mapName" in task and "pathName" in task:
            key = (str(task["mapName"]), str(task["pathName"]))
            if key not in cache:
                cache[key] = await source(*key)
    return cache


def _print_plan(settings: Settings, plan: ImportedPlan, schedule: Path | None = None) -> None:
    """The plan as mission files; with ``schedule`` (the file's path) as one schedule file."""
    from ..missions.files import dump_mission

    if schedule is not None:
        _print_schedule(settings, plan, schedule)
        return
    if settings.json:
        data = {
            "missions": [
                m.model_dump(mode="json", by_alias=True, exclude_defaults=True)
                for m in plan.missions
            ],
            "windows": [window.as_dict() for window in plan.windows],
            "notes": plan.notes,
        }
        out_console().print(json.dumps(data), markup=False)
        return
    documents = []
    windows = {id(window.mission): window for window in plan.windows}
    for mission in plan.missions:
        header = ""
        window = windows.get(id(mission))
        if window is not None:
            days = ",".join(str(day) for day in window.days)
            header = f"# window: days {days} (1 Monday … 7 Sunday), {window.start}-{window.stop}\n"
        documents.append(header + dump_mission(mission))
    notes = "".join(f"# note: {note}\n" for note in plan.notes)
    out_console().print(notes + "---\n".join(documents), markup=False, end="")


def _print_schedule(settings: Settings, plan: ImportedPlan, file: Path) -> None:
    from ..missions.schedule_model import dump_schedule, schedule_from_plan

    if not plan.windows:
        fail(f"--schedule: {file} has no time windows (a timeTask.json has)")
    try:
        schedule = schedule_from_plan(plan, name=file.stem)
    except ValueError as exc:
        fail(f"--schedule: {exc}")
    if settings.json:
        data = {"schedule": schedule.model_dump(mode="json", by_alias=True), "notes": plan.notes}
        out_console().print(json.dumps(data), markup=False)
        return
    notes = "".join(f"# note: {note}\n" for note in plan.notes)
    zone = "# time_zone: the robot's zone (timeTask.json's times are the robot's local time)\n"
    out_console().print(notes + zone + dump_schedule(schedule), markup=False, end="")


def _scheduled(
    settings: Settings, file: Path, kind: PlanFormat | None
) -> tuple[ImportedPlan, list[WindowCheck]] | None:
    """A schedule file (a top-level ``windows:``) as a plan and its window checks; None for
    anything else. A schedule that does not load: every problem, exit 2."""
    from ..missions.files import MissionFileError
    from ..missions.schedule_model import is_schedule, load_schedule, schedule_plan

    if kind not in (None, "mission") or file.suffix == ".json":
        return None
    try:
        if not is_schedule(_read(file)):
            return None
    except UnicodeDecodeError:
        return None  # the plan's loader names it
    try:
        return schedule_plan(load_schedule(file))
    except MissionFileError as exc:
        file_failure(settings, exc)


def file_failure(settings: Settings, exc: Any) -> NoReturn:
    """A plan file that does not load: every problem, exit 2."""
    if settings.json:
        problems = [
            {"severity": "error", "line": d.line, "step": d.step, "name": d.name,
             "message": d.message}
            for d in exc.details
        ]  # fmt: skip
        out_console().print(
            json.dumps({"file": exc.source, "ok": False, "problems": problems}), markup=False
        )
    else:
        from .output import err_console

        for line in exc.problems:
            err_console().print(f"error: {line}", markup=False, highlight=False)
    raise typer.Exit(int(ExitCode.USAGE))


@mission_app.command("check")
def check(
    ctx: typer.Context,
    file: Annotated[Path, typer.Argument(help="A mission file, timeTask.json or Nav2 file.")],
    plan_format: FormatOption = "auto",
    points: PointsOption = None,
    port: PortOption = None,
    strict: Annotated[
        bool, typer.Option("--strict", help="Warnings fail the check too (exit 2).")
    ] = False,
    json_output: JsonFlag = False,
) -> None:
    """Check a plan or a schedule before it runs (with --port: against the robot); exit 0,
    or 2 naming every problem."""
    settings = settings_of(ctx)
    settings.json = settings.json or json_output
    kind = plan_format_of(plan_format)
    with_robot = _port(settings, port)
    with plan_errors():
        scheduled = _scheduled(settings, file, kind)
    checks = scheduled[1] if scheduled is not None else []
    if not with_robot:
        with plan_errors():
            if scheduled is not None:
                plan = scheduled[0]
            else:
                plan = load_plan_file(settings, file, kind, point_source(points), False, True, None)
        found = _run_checks(plan, None, checks)
        raise typer.Exit(_report(settings, file, plan, found, strict, False))

    async def body(robot: Robot) -> int:
        from ..missions.check import check_plan

        source = robot_points(robot)
        if scheduled is not None:
            plan = scheduled[0]
        elif points is None and source is not None:
            plan = await load_plan_from_robot(settings, file, kind, source, False, True, None)
        else:
            with plan_errors():
                plan = load_plan_file(settings, file, kind, point_source(points), False, True, None)
        found = await check_plan(plan, robot=robot, window_checks=checks)
        return _report(settings, file, plan, found, strict, True)

    run_robot(settings, body)


def _run_checks(
    plan: ImportedPlan, robot: None, checks: list[WindowCheck]
) -> list[tuple[str, Problem]]:
    import asyncio

    from ..missions.check import check_plan

    return asyncio.run(check_plan(plan, robot=robot, window_checks=checks))


def _report(
    settings: Settings,
    file: Path,
    plan: ImportedPlan,
    found: list[tuple[str, Problem]],
    strict: bool,
    robot: bool,
) -> int:
    """Print the problems; the exit code: 2 with an error (or, ``strict``, a warning)."""
    failing = {"error", "warning"} if strict else {"error"}
    ok = not any(problem.severity in failing for _, problem in found)
    several = len(plan.missions) > 1
    if settings.json:
        problems = [{"mission": name, **problem.as_dict()} for name, problem in found]
        data = {"file": str(file), "ok": ok, "problems": problems}
        if robot:
            print_json(settings, data)
        else:
            out_console().print(json.dumps(data), markup=False)
    else:
        console = out_console()
        for name, problem in found:
            prefix = f"{name}: " if several else ""
            console.print(f"{file}: {prefix}{problem}", markup=False, highlight=False)
        counts = {kind: sum(p.severity == kind for _, p in found) for kind in ("error", "warning")}
        verdict = "ok" if ok else "not ok"
        tally = ", ".join(f"{n} {kind}{'' if n == 1 else 's'}" for kind, n in counts.items())
        console.print(f"{file}: {verdict}: {tally}", markup=False, highlight=False)
    return int(ExitCode.OK if ok else ExitCode.USAGE)
