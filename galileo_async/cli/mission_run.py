"""``galileo mission run`` and ``galileo fleet mission run``: a mission with live progress.

The command functions and ``register``/``register_fleet``, which add them to the
``galileo mission`` group and to ``galileo fleet`` (a ``mission`` group with ``run``).
"""

from __future__ import annotations

import json
from collections.abc import Awaitable, Callable
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import anyio
import anyio.lowlevel
import typer

from ..errors import InvalidArgument
from ..fleet.file import load_fleet_file
from ..links import link_kind
from ..missions.capabilities import REST_API, needs
from ..missions.events import LoopStarted, MissionEnded, MissionEvent, StepEnded
from ..missions.model import Mission, WaitStep, step_paths
from ..missions.report import MissionRejected, MissionReport
from .mission import (
    FormatOption,
    PointsOption,
    load_plan_file,
    load_plan_from_robot,
    plan_errors,
    plan_format_of,
    point_source,
    robot_points,
)
from .output import err_console, out_console, timestamp
from .releases import parse_releases, triggered
from .runner import (
    ExitCode,
    Settings,
    fail,
    is_sim,
    print_error,
    robot_url,
    run,
    run_robot,
    settings_of,
)

if TYPE_CHECKING:
    from ..missions.importers import ImportedPlan, PlanFormat
    from ..robot import Robot
    from ..testing.robot import SimLink

__all__ = [
    "SIM_UNTIL",
    "checked",
    "event_line",
    "fleet_mission_run",
    "mission_exit_code",
    "mission_of",
    "mission_run",
    "print_rejected",
    "register",
    "register_fleet",
]

#: Simulated seconds after which ``--sim`` stops a mission that is still running (a day).
SIM_UNTIL = 24 * 3600.0

#: Exit codes by how the mission ended; "failed" goes by the failed step's ending.
_ENDING_CODES = {
    "completed": ExitCode.OK,
    "stopped": ExitCode.CANCELLED,
    "cancelled": ExitCode.INTERRUPTED,
    "link lost": ExitCode.CONNECTION,
}
_STEP_CODES = {
    "rejected": ExitCode.REJECTED,
    "aborted": ExitCode.ABORTED,
    "stalled": ExitCode.ABORTED,
    "timeout": ExitCode.TIMEOUT,
}

FileArgument = Annotated[
    Path,
    typer.Argument(
        help="A mission file (YAML; JSON is YAML too), timeTask.json or Nav2 file.",
        dir_okay=False,
    ),
]
TaskOption = Annotated[
    str | None,
    typer.Option(
        "--task",
        metavar="NAME",
        help="A file of several tasks (timeTask.json): the one to run, by its name or its "
        "first word (autoRunTasks[0]).",
    ),
]
ReleaseOption = Annotated[
    list[str] | None,
    typer.Option(
        "--release",
        metavar="NAME=key|file:PATH|http:[HOST:]PORT|mqtt:URL",
        help="What releases the wait NAME: key (Enter on stdin), file:PATH (once PATH "
        "exists), http:[HOST:]PORT (POST /release/NAME there; host 127.0.0.1 by default) or "
        "mqtt:mqtt://HOST[:PORT]/TOPIC (any message on TOPIC). A POST or message before "
        "the wait starts is remembered once. Repeatable.",
    ),
]
JsonOption = Annotated[bool, typer.Option("--json", help="A JSON line per progress event.")]


def mission_of(plan: ImportedPlan, file: Path, task: str | None) -> Mission:
    """The one mission of ``plan`` that runs: its only one, or the one ``task`` names (its
    whole name or its first word, e.g. ``autoRunTasks[0]``); else exit 2 naming them."""
    names = [mission.mission for mission in plan.missions]
    if task is None and len(plan.missions) == 1:
        return plan.missions[0]
    for mission in plan.missions:
        if task in (mission.mission, mission.mission.split(" ")[0]):
            return mission
    listed = "; ".join(repr(name) for name in names) or "none"
    if task is None:
        fail(f"{file} has {len(names)} tasks: name the one to run with --task ({listed})",
             ExitCode.USAGE)  # fmt: skip
    fail(f"{file} has no task {task!r} (it has: {listed})", ExitCode.USAGE)


def checked(file: Path, mission: Mission) -> bool:
    """check_static before anything moves: print its warnings and errors; False on an error."""
    from ..missions.check import check_static

    problems = [p for p in check_static(mission) if p.severity != "note"]
    for problem in problems:
        if problem.severity == "error":
            where = str(problem).partition(": ")[2]  # without "error: ", which print_error says
            print_error(f"{file}: {where}", kind="usage", code=ExitCode.USAGE)
        else:
            err_console().print(f"{file}: {problem}", markup=False, highlight=False)
    return not any(problem.severity == "error" for problem in problems)


def _needs_robot_points(file: Path, kind: PlanFormat | None, points: Path | None) -> bool:
    """True for a timeTask.json without --points: its paths' points come from the robot."""
    from ..missions.importers import detect_format

    if points is not None:
        return False
    with plan_errors():
        return (kind or detect_format(file)) == "timetask"


def mission_exit_code(report: MissionReport) -> int:
    """0 completed, 5 stopped, 7 link lost, 130 cancelled; a failure by its step's ending."""
    if report.ending != "failed":
        return int(_ENDING_CODES[report.ending])
    last = report.steps[-1].ending if report.steps else "failed"
    return int(_STEP_CODES.get(last, ExitCode.ERROR))


def event_line(event: MissionEvent) -> str | None:
    """The text line of a progress event (None: no line)."""
    if isinstance(event, StepEnded):
        step = event.step
        name = f" ({step.name})" if step.name else ""
        error = f": {step.error}" if step.error else ""
        return (
            f"{step.path}{name} {step.action} {step.ending} in {step.duration:.1f} s, "
            f"{step.distance_m:.1f} m{error}"
        )
    if isinstance(event, LoopStarted):
        count = "" if event.count is None else f" of {event.count}"
        return f"{event.path} loop {event.iteration}{count}"
    if isinstance(event, MissionEnded):
        report = event.report
        took = report.ended - report.started
        return (
            f"mission {report.mission!r} {report.ending}: {len(report.steps)} steps, "
            f"{report.loops_done} loops, {report.distance_m:.1f} m in {took:.1f} s"
        )
    return None


def _printer(as_json: bool, robot: str | None = None) -> Callable[[MissionEvent], None]:
    console = out_console()

    def show(event: MissionEvent) -> None:
        if as_json:
            named = {} if robot is None else {"robot": robot}
            line = json.dumps({"time": timestamp(), **named, **event.to_json()})
            console.print(line, markup=False, soft_wrap=True, highlight=False)
            return
        text = event_line(event)
        if text is not None:
            prefix = "" if robot is None else f"{robot}: "
            console.print(prefix + text, markup=False, soft_wrap=True, highlight=False)

    return show


def print_rejected(exc: MissionRejected) -> int:
    for problem in exc.problems:
        print_error(f"mission {exc.mission!r}: {problem}", kind="usage", code=ExitCode.USAGE)
    return int(ExitCode.USAGE)


def mission_run(
    ctx: typer.Context,
    file: FileArgument,
    sim: Annotated[
        bool,
        typer.Option(
            "--sim",
            help="Play it on the built-in simulator on a virtual clock (hours in seconds) and "
            "print the timeline; every wait is released at once.",
        ),
    ] = False,
    until: Annotated[
        float,
        typer.Option("--until", min=1.0, help="--sim: stop it after this many simulated s."),
    ] = SIM_UNTIL,
    journal: Annotated[
        Path | None, typer.Option("--journal", help="Record the run in this file.")
    ] = None,
    resume: Annotated[
        bool, typer.Option("--resume", help="Start where the --journal file says the run was.")
    ] = False,
    release: ReleaseOption = None,
    plan_format: FormatOption = "auto",
    points: PointsOption = None,
    task: TaskOption = None,
    offload: Annotated[
        bool,
        typer.Option(
            "--offload",
            help="Send it to the robot's task chain as one task (http://) and follow it: it "
            "goes on when this host's link drops. With --sim: on the simulator's HTTP face.",
        ),
    ] = False,
    json_output: JsonOption = False,
) -> None:
    """Run a mission with a line per step; the exit code tells how it ended.

    0 completed, 2 rejected before anything moved, 3/4/6 a step failed (rejected, aborted
    or stalled, timeout), 1 another failure, 5 stopped by a user stop, 7 link lost; Ctrl-C,
    SIGTERM: the robot is stopped, 130/143.
    """
    settings = settings_of(ctx)
    settings.json = settings.json or json_output
    kind = plan_format_of(plan_format)
    from_robot = (
        not sim
        and _needs_robot_points(file, kind, points)
        and link_kind(robot_url(settings)) == "http"
    )
    loaded: Mission | None = None
    if not from_robot:
        with plan_errors():
            plan = load_plan_file(settings, file, kind, point_source(points), False, True, None)
        loaded = mission_of(plan, file, task)
        if not checked(file, loaded):
            raise typer.Exit(int(ExitCode.USAGE))
    releases = parse_releases(release)
    show = _printer(settings.json)
    if offload:
        _offload_usage(settings, sim, loaded, journal is not None or resume or bool(releases))
    if sim:
        assert loaded is not None
        mission = loaded

        async def simulated() -> int:
            if offload:
                return await _play_offload(mission, show, until)
            return await _play(mission, show, until, settings.json)

        run(settings, simulated)

    async def body(robot: Robot) -> int:
        from ..missions.runner import run_mission

        mission = loaded
        if mission is None:
            source = robot_points(robot)
            assert source is not None  # an http:// link has its REST part
            plan = await load_plan_from_robot(settings, file, kind, source, False, True, None)
            mission = mission_of(plan, file, task)
            if not checked(file, mission):
                return int(ExitCode.USAGE)
        if offload:
            return await _offload(robot, mission, show)
        try:
            async with triggered(releases) as given:
                report = await run_mission(
                    robot, mission, releases=given, journal=journal, resume=resume,
                    on_progress=show,
                )  # fmt: skip
        except MissionRejected as exc:
            return print_rejected(exc)
        return mission_exit_code(report)

    run_robot(settings, body, navigation=None, moving=True)


async def _play(
    mission: Mission, show: Callable[[MissionEvent], None], until: float, as_json: bool
) -> int:
    """``--sim``: the mission on simulated_robot() (http:// when a step needs it)."""
    import asyncio

    from ..testing import play_mission, simulated_robot

    steps = [step for _, step in step_paths(mission.steps)]
    link: SimLink = "http" if any(REST_API in needs(step) for step in steps) else "sim"
    waits = {step.wait.release for step in steps if isinstance(step, WaitStep)}
    released: dict[str, Callable[[], Awaitable[object]]] = dict.fromkeys(
        waits, anyio.lowlevel.checkpoint
    )
    async with simulated_robot(link=link) as (robot, _):
        stopping: list[asyncio.Task[Any]] = []

        def stop() -> None:
            stopping.append(asyncio.ensure_future(robot.stop()))

        try:
            play = await play_mission(robot, mission, faults={until: stop}, releases=released)
        except MissionRejected as exc:
            return print_rejected(exc)
        finally:
            if stopping:
                await asyncio.wait(stopping)
    if as_json:
        for event in play.events:
            show(event)
    else:
        console = out_console()
        for line in play.timeline():
            console.print(line, markup=False, soft_wrap=True, highlight=False)
    return mission_exit_code(play.report)


def _offload_usage(
    settings: Settings, sim: bool, mission: Mission | None, host_options: bool
) -> None:
    """Exit 2 unless --offload can go: an http:// robot (or --sim), no options of a run on
    this host, and a mission (when loaded) the task chain can run."""
    from ..missions.offload import OffloadRejected, offload_problems

    if host_options:
        fail("--offload: the robot runs the plan; --journal, --resume and --release are for "
             "a run on this host", ExitCode.USAGE)  # fmt: skip
    if not sim and link_kind(robot_url(settings)) != "http":
        fail("--offload needs the robot's task chain: an http:// or https:// robot (-p URL) "
             "or --sim", ExitCode.USAGE)  # fmt: skip
    if mission is not None and (problems := offload_problems(mission)):
        raise typer.Exit(print_rejected(OffloadRejected(mission.mission, problems)))


async def _offload(robot: Robot, mission: Mission, show: Callable[[MissionEvent], None]) -> int:
    """offload_mission on ``robot``, shown as a run's events; the exit code as a run's."""
    from ..missions.offload import ChainProgress, offload_mission
    from ..missions.offload_events import OffloadEvents

    events = OffloadEvents(mission)

    def progress(seen: ChainProgress) -> None:
        for event in events.of(seen):
            show(event)

    try:
        report = await offload_mission(robot, mission, on_progress=progress)
    except MissionRejected as exc:
        return print_rejected(exc)
    ended = events.ended(report)
    show(ended)
    return mission_exit_code(ended.report)


async def _play_offload(
    mission: Mission, show: Callable[[MissionEvent], None], until: float
) -> int:
    """``--sim --offload``: the mission on simulated_robot(link="http")'s task chain."""
    import asyncio

    from ..testing import simulated_robot

    async with simulated_robot(link="http") as (robot, _):
        stopping: list[asyncio.Task[Any]] = []

        def stop() -> None:
            stopping.append(asyncio.ensure_future(robot.stop()))

        timer = asyncio.get_running_loop().call_later(until, stop)
        try:
            return await _offload(robot, mission, show)
        finally:
            timer.cancel()
            if stopping:
                await asyncio.wait(stopping)


def fleet_mission_run(
    ctx: typer.Context,
    file: FileArgument,
    per_robot: Annotated[
        list[str] | None,
        typer.Option(
            "--per-robot",
            metavar="NAME=FILE",
            help="Robot NAME runs the mission in FILE instead of the shared one. Repeatable.",
        ),
    ] = None,
    release: ReleaseOption = None,
    plan_format: FormatOption = "auto",
    points: PointsOption = None,
    task: TaskOption = None,
    json_output: JsonOption = False,
) -> None:
    """Run a mission on every robot of the fleet at once; the first stop stops them all.

    A line per step, prefixed by the robot's name (--json: a JSON line per event with
    "robot"). The exit code is the first robot's (in file order) that did not complete.
    """
    settings = settings_of(ctx)
    settings.json = settings.json or json_output
    if settings.fleet is None:
        fail("fleet commands need a fleet file: galileo --fleet fleet.toml fleet …", ExitCode.USAGE)
    try:
        spec = load_fleet_file(settings.fleet)
    except InvalidArgument as exc:
        fail(str(exc), ExitCode.USAGE)
    kind, source = plan_format_of(plan_format), point_source(points)

    def load(path: Path) -> Mission:
        with plan_errors():
            plan = load_plan_file(settings, path, kind, source, False, True, None)
        mission = mission_of(plan, path, task)
        if not checked(path, mission):
            raise typer.Exit(int(ExitCode.USAGE))
        return mission

    missions = dict.fromkeys(spec.ports, load(file))
    for entry in per_robot or []:
        name, _, path = entry.partition("=")
        if name not in spec.ports or not path:
            fail(f"--per-robot {entry!r}: give NAME=FILE, NAME in the fleet", ExitCode.USAGE)
        missions[name] = load(Path(path))
    releases = parse_releases(release)
    shows = {name: _printer(settings.json, name) for name in missions}

    async def main() -> int:
        async with spec.connect() as fleet:
            # As run_robot's navigation=None: a sim:// robot is a fresh one, navigation closed.
            simulated = [name for name in missions if is_sim(spec.ports[name])]
            opened = await fleet.each(lambda robot: robot.start_navigation(), simulated)
            for result in opened.values():
                if result.error is not None:
                    raise result.error
            try:
                async with triggered(releases) as given:
                    reports = await fleet.run_missions(
                        missions, releases=given,
                        on_progress=lambda name, event: shows[name](event),
                    )  # fmt: skip
            except MissionRejected as exc:
                return print_rejected(exc)
        codes = [mission_exit_code(report) for report in reports.values()]
        return next((code for code in codes if code != 0), 0)

    run(settings, main)


def register(mission_app: typer.Typer) -> None:
    """Add ``run`` to the ``galileo mission`` group."""
    mission_app.command("run")(mission_run)


def register_fleet(fleet_app: typer.Typer) -> None:
    """Add the group ``mission`` with ``run`` to ``galileo fleet``."""
    group = typer.Typer(help="Missions on every robot of the fleet.", no_args_is_help=True)
    group.command("run")(fleet_mission_run)
    fleet_app.add_typer(group, name="mission")
