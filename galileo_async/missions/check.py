"""Checks before a mission moves anything: of the plan alone, and against a connected robot.

check_static(mission) needs nothing; ``await check_mission(mission, robot=robot)`` adds
what the robot's link can tell: its targets (http:// reads each path's, serial the
``map_targets`` count), the steps its link can run, its maps, and a battery budget from
the motion model's speed and drain. Schedules check their own windows (``window_checks``
of check_plan).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING, Any, Literal

from .capabilities import Unsupported, capabilities_of, unreleased, unsupported
from .model import (
    ChargeStep,
    DwellStep,
    GotoPointStep,
    GotoPoseStep,
    GotoStep,
    LoopStep,
    Mission,
    SayStep,
    SwitchMapStep,
    WaitStep,
    step_action,
    step_paths,
)

if TYPE_CHECKING:
    from .importers import ImportedPlan, ImportedWindow
    from .robot_api import MissionRobot

__all__ = [
    "BUDGET",
    "Budget",
    "Problem",
    "Severity",
    "WindowCheck",
    "check_mission",
    "check_plan",
    "check_static",
    "has_errors",
]

#: error: the mission cannot run as written; warning: it runs, likely not as meant;
#: note: worth knowing (a step that needs http://, a figure of the budget).
Severity = Literal["error", "warning", "note"]

#: A dwell or a wait this long (s) is probably a unit mistake.
LONG_WAIT = 8 * 3600.0


@dataclass(frozen=True)
class Problem:
    """One finding: the step (its path and name; None for the mission), what, how bad."""

    step: str | None
    name: str | None
    message: str
    severity: Severity = "error"

    def __str__(self) -> str:
        named = "" if self.name is None else f" (name {self.name!r})"
        where = "mission" if self.step is None else self.step
        return f"{self.severity}: {where}{named}: {self.message}"

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready: severity, step, name, message."""
        return asdict(self)


def has_errors(problems: Iterable[Problem]) -> bool:
    """True when any problem is an error."""
    return any(problem.severity == "error" for problem in problems)


@dataclass(frozen=True)
class Budget:
    """The motion model a battery budget uses: m/s, rad/s, V/s of driving and of standing."""

    speed: float = 0.8
    turn_rate: float = 1.5
    drain: float = 0.0005
    #: The voltage the battery is empty at (0 % of the 24 V pack's curve).
    empty_volts: float = 22.0


#: The simulator's motion model (galileo_async.sim.SimConfig's max_speed, max_turn_rate,
#: power_drain) and the VDA 5050 adapter's empty voltage; a test keeps them equal.
BUDGET = Budget()


def check_static(mission: Mission) -> list[Problem]:
    """What is wrong or doubtful in ``mission`` itself, in file order."""
    problems: list[Problem] = []
    problems += _unreachable(mission.steps, "steps", _jump_targets(mission))
    lacking = _lacking(mission, frozenset())
    waits = {path: step.wait.release for path, step in unreleased(mission, ())}
    order = {step.name: index for index, (_, step) in enumerate(step_paths(mission.steps))}
    for index, (path, step) in enumerate(step_paths(mission.steps)):
        problems += [Problem(path, step.name, text, kind) for kind, text in _step_doubts(step)]
        target = step.on_failure.goto
        if target is not None and order[target] <= index:
            problems.append(Problem(path, step.name, (
                f"on_failure goes back to {target!r}: if this step keeps failing, the mission "
                "never ends (nothing bounds the jumps); go forward (e.g. to a dock step) or "
                "abort"
            ), "warning"))  # fmt: skip
        if path in lacking:
            problems.append(Problem(path, step.name, lacking[path].reason, "note"))
        if path in waits:
            problems.append(Problem(path, step.name, (
                f"a run needs the release {waits[path]!r} (--release {waits[path]}=key|file:PATH|"
                "http:PORT|mqtt:URL, run_mission's releases); check cannot know it"
            ), "note"))  # fmt: skip
    return problems


def _lacking(mission: Mission, capabilities: frozenset[str]) -> dict[str, Unsupported]:
    """The steps a link with ``capabilities`` cannot run, by path."""
    return {found.path: found for found in unsupported(mission, capabilities)}


def _jump_targets(mission: Mission) -> set[str]:
    return {step.on_failure.goto for _, step in step_paths(mission.steps) if step.on_failure.goto}


def _unreachable(steps: Sequence[Any], prefix: str, targets: set[str]) -> list[Problem]:
    problems: list[Problem] = []
    forever: str | None = None
    for index, step in enumerate(steps):
        path = f"{prefix}[{index}]"
        if step.name in targets:
            forever = None  # a failure jumps here: this step and the next are reachable
        if forever is not None:
            problems.append(Problem(path, step.name, (
                f"never reached: the loop {forever} before it runs until stopped (a "
                "schedule's window closing ends it; give the loop a count otherwise)"
            ), "warning"))  # fmt: skip
        if isinstance(step, LoopStep):
            problems += _unreachable(step.loop.steps, f"{path}.loop.steps", targets)
            if step.loop.count is None and forever is None:
                forever = path if step.name is None else f"{path} ({step.name!r})"
    return problems


def _step_doubts(step: Any) -> list[tuple[Severity, str]]:
    doubts: list[tuple[Severity, str]] = []
    timeout = step.timeout
    if isinstance(step, DwellStep):
        if step.dwell == 0:
            doubts.append(("warning", "dwell 0 does nothing"))
        if step.dwell > LONG_WAIT:
            doubts.append(("warning", f"dwell {step.dwell:g} s is over 8 hours (seconds?)"))
        if timeout is not None and timeout <= step.dwell:
            doubts.append(("error", f"timeout {timeout:g} s ends the dwell of {step.dwell:g} s"))
    elif isinstance(step, WaitStep):
        release = step.wait
        if release.timeout is None and timeout is None:
            doubts.append(("warning", (
                f"wait for {release.release!r} has no timeout: without the release the "
                "mission waits for ever"
            )))  # fmt: skip
        elif release.timeout is not None and timeout is not None and timeout < release.timeout:
            doubts.append(("warning", (
                f"the step's timeout {timeout:g} s ends it before the wait's {release.timeout:g} s"
            )))  # fmt: skip
    elif isinstance(step, ChargeStep):
        volts = step.charge.until_volts
        if volts is not None and not 22.0 <= volts <= 29.4:
            doubts.append(("warning", f"until_volts {volts:g} V is outside a 24 V pack's range"))
    elif isinstance(step, GotoStep | GotoPointStep | GotoPoseStep) and timeout is not None:
        if timeout < 5:
            doubts.append(("warning", f"timeout {timeout:g} s is short for a goal"))
    elif step_action(step) == "call" and timeout is not None and timeout < step.call.timeout:
        doubts.append(("warning", (
            f"the step's timeout {timeout:g} s is shorter than the call's {step.call.timeout:g} s"
        )))  # fmt: skip
    return doubts


async def check_mission(
    mission: Mission, *, robot: MissionRobot | None = None, budget: Budget = BUDGET
) -> list[Problem]:
    """check_static, then (with ``robot``) what the robot's link tells: targets, steps its
    link can run, map names, and the battery a loop takes against the battery it has."""
    problems = check_static(mission)
    if robot is None:
        return problems
    # The robot's link settles whether the http:// steps can run: its problems say so.
    notes = {Problem(f.path, f.name, f.reason, "note") for f in unsupported(mission, ())}
    static = [problem for problem in problems if problem not in notes]
    return static + await _robot_problems(mission, robot, budget)


#: Points of a map's path by (map, path); (None, None) is the map the robot is on.
_Points = dict[tuple[str | None, str | None], list[tuple[float, float]] | None]


async def _robot_problems(mission: Mission, robot: MissionRobot, budget: Budget) -> list[Problem]:
    problems: list[Problem] = []
    http = robot.http
    maps = await http.maps() if http is not None else None
    points: _Points = {}
    speed = budget.speed
    if http is not None:
        navigation_speed = await http.navigation_speed()
        speed = navigation_speed if navigation_speed > 0 else speed
    where: tuple[str | None, str | None] = (None, None)
    loops: dict[str, tuple[str | None, str | None]] = {}
    lacking = _lacking(mission, capabilities_of(robot))
    for path, step in step_paths(mission.steps):
        if isinstance(step, LoopStep):
            loops[path] = where
        if path in lacking:
            problems.append(Problem(path, step.name, lacking[path].reason))
        if isinstance(step, GotoPointStep) and http is None and robot.map_targets is None:
            problems.append(Problem(path, step.name, (
                "goto_point needs the number of targets in the robot's map: connect with "
                "map_targets=N (galileo --map-targets N)"
            )))  # fmt: skip
        if isinstance(step, SwitchMapStep):
            where = (step.switch_map.map, step.switch_map.path)
            if maps is not None and step.switch_map.map not in maps:
                problems.append(Problem(path, step.name, (
                    f"map {step.switch_map.map!r} is not on the robot (it has: "
                    f"{', '.join(maps) or 'none'})"
                )))  # fmt: skip
                where = ("", "")  # unknown map: no target checks after it
        if isinstance(step, GotoStep):
            known = await _points(robot, where, points)
            count = len(known) if known is not None else _count(robot, where)
            if count is not None and step.goto >= count:
                on = "the robot's map" if where == (None, None) else f"map {where[0]!r}"
                problems.append(Problem(path, step.name, (
                    f"target {step.goto} is not in {on}: it has {count} targets "
                    f"({_ids(count)})"
                )))  # fmt: skip
    for path, step in step_paths(mission.steps):
        if isinstance(step, LoopStep) and step.loop.count is not None:
            known = await _points(robot, loops[path], points)
            problems += _battery(path, step, robot, budget, speed, known)
    return problems


def _ids(count: int) -> str:
    return "none" if count == 0 else "0" if count == 1 else f"0-{count - 1}"


def _count(robot: MissionRobot, where: tuple[str | None, str | None]) -> int | None:
    """The target count a non-http link knows: only for the map the robot is on."""
    return robot.map_targets if where == (None, None) else None


async def _points(
    robot: MissionRobot, where: tuple[str | None, str | None], cache: _Points
) -> list[tuple[float, float]] | None:
    if where not in cache:
        cache[where] = None
        if robot.http is not None and where != ("", ""):
            map_name, path_name = where
            if map_name is not None and path_name is None:
                cache[where] = None  # the map's default path: the API does not say which
            else:
                targets = await robot.http.targets(map_name, path_name)
                cache[where] = [(target.x, target.y) for target in targets]
    return cache[where]


def _battery(
    path: str,
    step: LoopStep,
    robot: MissionRobot,
    budget: Budget,
    speed: float,
    known: list[tuple[float, float]] | None,
) -> list[Problem]:
    """A warning when a finite loop's estimated drain is above the battery left."""
    status = robot.status
    if status is None or not status.power or step.loop.count is None:
        return []
    volts = status.power
    here = (status.current_pose_x or 0.0, status.current_pose_y or 0.0)
    seconds = _pass_seconds(step.loop.steps, known, here, speed, budget)
    if seconds is None:
        return []
    total = seconds * step.loop.count
    drain = total * budget.drain
    left = volts - budget.empty_volts
    if drain <= left:
        return []
    return [Problem(path, step.name, (
        f"about {_duration(total)} for {step.loop.count} passes, {drain:.2f} V of battery "
        f"by the motion model; the robot has {max(left, 0.0):.2f} V left ({volts:.2f} V, "
        f"empty at {budget.empty_volts:g} V): add a charge step"
    ), "warning")]  # fmt: skip


def _pass_seconds(
    steps: Sequence[Any],
    known: list[tuple[float, float]] | None,
    start: tuple[float, float],
    speed: float,
    budget: Budget,
) -> float | None:
    """Seconds one pass of ``steps`` takes by the motion model; None when a step's place or
    length is unknown (a target without coordinates, a wait, a charge)."""
    seconds, here = 0.0, start
    for step in steps:
        there: tuple[float, float] | None = None
        if isinstance(step, GotoStep):
            if known is None or step.goto >= len(known):
                return None
            there = known[step.goto]
        elif isinstance(step, GotoPointStep | GotoPoseStep):
            point = step.goto_point if isinstance(step, GotoPointStep) else step.goto_pose
            there = (point.x, point.y)
        elif isinstance(step, DwellStep):
            seconds += step.dwell
        elif isinstance(step, SayStep):
            continue
        elif isinstance(step, LoopStep) and step.loop.count is not None:
            inner = _pass_seconds(step.loop.steps, known, here, speed, budget)
            if inner is None:
                return None
            seconds += inner * step.loop.count
        else:
            return None
        if there is not None:
            distance = math.dist(here, there)
            seconds += distance / speed + math.pi / 2 / budget.turn_rate
            here = there
    return seconds


def _duration(seconds: float) -> str:
    minutes = round(seconds / 60)
    return f"{minutes // 60} h {minutes % 60} min" if minutes >= 60 else f"{minutes} min"


#: A check of a schedule's windows (overlaps, gaps): the schedule's module provides them.
WindowCheck = Callable[[Sequence["ImportedWindow"]], list[Problem]]


async def check_plan(
    plan: ImportedPlan,
    *,
    robot: MissionRobot | None = None,
    window_checks: Sequence[WindowCheck] = (),
    budget: Budget = BUDGET,
) -> list[tuple[str, Problem]]:
    """check_mission on every mission of an imported plan, and ``window_checks`` on its
    windows: (mission name, problem) pairs; the windows' under the name "schedule"."""
    found: list[tuple[str, Problem]] = []
    for mission in plan.missions:
        for problem in await check_mission(mission, robot=robot, budget=budget):
            found.append((mission.mission, problem))
    for window_check in window_checks:
        found += [("schedule", problem) for problem in window_check(plan.windows)]
    return found
