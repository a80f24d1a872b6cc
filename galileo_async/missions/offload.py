"""A mission offloaded to the robot's own task chain over http:// (docs/missions.md,
"Offloading to the robot").

``offload_problems`` names every step the chain cannot run as the mission says;
``plan_offload`` turns a mission into the chain's actions; ``offload_mission`` asks the
robot for what the plan needs (its targets, its charger's pose), posts one task, starts
it and follows it with GET /task once a period. The robot runs the plan itself: a follower
that cannot reach it retries with back-off and the chain goes on meanwhile.
"""

from __future__ import annotations

import asyncio
import logging
import math
from collections.abc import Awaitable, Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal, TypeVar

import anyio
from pydantic import BaseModel, ConfigDict, Field

from ..errors import GalileoConnectionError, HttpError, InvalidArgument, NotSupported
from ..robot.http_part import HttpPart, NavPoint
from ..robot.task_chain import (
    TASK_ENDINGS,
    Action,
    CallbackAction,
    ChargeAction,
    LocalMoveAction,
    NavAction,
    SleepAction,
    Task,
    WaitReqAction,
)
from .exit_stop import exit_stop
from .model import (
    CallStep,
    ChargeStep,
    DwellStep,
    GotoPointStep,
    GotoPoseStep,
    GotoStep,
    LocalMoveStep,
    LoopStep,
    Mission,
    SayStep,
    SwitchMapStep,
    WaitStep,
    step_action,
    step_paths,
)
from .report import MissionRejected

if TYPE_CHECKING:
    from ..robot import Robot

__all__ = [
    "CALL_TIMEOUT",
    "FOLLOW_PERIOD",
    "FOLLOW_TIMEOUT",
    "MAX_BACKOFF",
    "ActionRun",
    "ChainProgress",
    "OffloadEnding",
    "OffloadPlan",
    "OffloadRejected",
    "OffloadReport",
    "OffloadedStep",
    "offload_mission",
    "offload_problems",
    "plan_offload",
]

_log = logging.getLogger(__name__)
_T = TypeVar("_T")

#: Seconds between two looks at the task (the robot's own status looks once a second).
FOLLOW_PERIOD = 1.0
#: Seconds each call to the robot may take.
CALL_TIMEOUT = 5.0
#: Seconds the follower keeps trying after the robot's last answer, by default.
FOLLOW_TIMEOUT = 300.0
#: The longest wait between two tries while the robot does not answer.
MAX_BACKOFF = 30.0

#: How an offloaded mission ended, named as the runner's endings.
OffloadEnding = Literal["completed", "stopped", "failed", "link lost"]


class OffloadRejected(MissionRejected):
    """The mission cannot be offloaded (nothing was sent): one line per problem."""

    def __init__(self, mission: str, problems: list[str]) -> None:
        super().__init__(mission, problems)
        self.args = (f"mission {mission!r} cannot be offloaded: " + "; ".join(problems),)


# --- what the chain can run ----------------------------------------------------------


def _where(path: str, step: Any) -> str:
    return path if step.name is None else f"{path} ({step.name})"


def _chain_steps(mission: Mission) -> tuple[list[tuple[str, Any]], LoopStep | None]:
    """The steps the chain runs with their paths (a whole-mission loop's, else the
    mission's), and that loop."""
    steps = mission.steps
    loop = steps[0] if len(steps) == 1 and isinstance(steps[0], LoopStep) else None
    prefix = "steps" if loop is None else "steps[0].loop.steps"
    chain = [pair for pair in step_paths(steps) if pair[0].rpartition("[")[0] == prefix]
    return chain, loop


def _policy_problems(where: str, step: Any) -> list[str]:
    problems = []
    policy = step.on_failure
    if policy.retry or policy.then != "abort":
        said = [f"retry {policy.retry}"] if policy.retry else []
        if policy.then == "goto":
            said.append(f"goto {policy.goto}")
        elif policy.then == "skip":
            said.append("skip")
        problems.append(
            f"{where}: on_failure {', then '.join(said)}: the task chain ends at the first"
            " failed action (on_failure: abort)"
        )
    if step.timeout is not None:
        problems.append(f"{where}: timeout {step.timeout:g} s: the task chain has no step timeouts")
    return problems


def _call_problems(where: str, step: CallStep) -> list[str]:
    call, problems = step.call, []
    given = call.model_fields_set
    if call.headers:
        problems.append(f"{where}: call headers: the robot's callback_action sends none")
    if "expect_status" in given:
        problems.append(
            f"{where}: call expect_status: the robot's callback_action fails on any status"
            " of 400 or more and checks nothing else"
        )
    if call.expect_json is not None:
        problems.append(f"{where}: call expect_json: the robot's callback_action reads no answer")
    if "timeout" in given:
        problems.append(f"{where}: call timeout: the robot's callback_action has its own")
    if call.json_body is not None and not isinstance(call.json_body, dict):
        problems.append(f"{where}: call json: the robot's callback_action sends an object only")
    return problems


def _step_problems(
    where: str, step: Any, targets: Sequence[NavPoint] | None, in_loop: bool
) -> list[str]:
    problems = _policy_problems(where, step)
    if isinstance(step, LoopStep):
        problems.append(
            f"{where}: a loop inside the loop: the task chain loops only as a whole"
            if in_loop
            else f"{where}: a loop among other steps: the task chain loops only as a whole"
            " (make the loop the mission's only step)"
        )
    elif isinstance(step, SayStep):
        problems.append(f"{where}: say: the task chain has no speech action")
    elif isinstance(step, SwitchMapStep):
        problems.append(f"{where}: switch_map: the task chain cannot switch maps")
    elif isinstance(step, GotoStep) and targets is not None and step.goto >= len(targets):
        problems.append(
            f"{where}: goto {step.goto}: the robot's current map and path have no target"
            f" {step.goto} ({len(targets)} targets)"
        )
    elif isinstance(step, ChargeStep) and (
        step.charge.until_percent is not None or step.charge.until_volts is not None
    ):
        problems.append(
            f"{where}: charge until a battery level: the chain's charge_action ends once the"
            " robot charges"
        )
    elif isinstance(step, CallStep):
        problems += _call_problems(where, step)
    elif isinstance(step, WaitStep) and step.wait.timeout is not None:
        problems.append(
            f"{where}: wait timeout: the chain's wait_req_action waits until released, without one"
        )
    return problems


def offload_problems(mission: Mission, *, targets: Sequence[NavPoint] | None = None) -> list[str]:
    """Every reason ``mission`` cannot run as one task chain; empty when it can.

    ``targets``: the robot's targets (robot.http.targets()) to check goto ids against;
    None: not checked. The chain ends at the first failed action, so only on_failure
    abort (the default) is kept; a loop must be the mission's only step.
    """
    chain, loop = _chain_steps(mission)
    problems = [] if loop is None else _policy_problems(_where("steps[0]", loop), loop)
    for path, step in chain:
        problems += _step_problems(_where(path, step), step, targets, loop is not None)
    return problems


@dataclass(frozen=True)
class OffloadedStep:
    """One action of the chain and the mission step it runs."""

    path: str
    name: str | None
    action: str
    chain_action: Action


@dataclass(frozen=True)
class OffloadPlan:
    """A mission as one task: its actions in order, ``loop_flag``, and the passes (None: ever)."""

    name: str
    steps: tuple[OffloadedStep, ...]
    loop_flag: bool
    count: int | None

    @property
    def actions(self) -> list[Action]:
        """The chain's actions, as create_task takes them."""
        return [step.chain_action for step in self.steps]


def _chain_action(step: Any, targets: Sequence[NavPoint], dock: NavPoint | None) -> Action:
    if isinstance(step, GotoStep):
        target = targets[step.goto]
        return NavAction(x=target.x, y=target.y, theta=target.theta)
    if isinstance(step, GotoPointStep):
        # A point has no heading: theta 0, where goto_point's own goal ends on every link.
        return NavAction(x=step.goto_point.x, y=step.goto_point.y, theta=0.0)
    if isinstance(step, GotoPoseStep):
        pose = step.goto_pose
        return NavAction(x=pose.x, y=pose.y, theta=pose.theta)
    if isinstance(step, DwellStep):
        return SleepAction(wait_time=step.dwell)
    if isinstance(step, ChargeStep):
        assert dock is not None
        return ChargeAction(x=dock.x, y=dock.y, theta=dock.theta)
    if isinstance(step, LocalMoveStep):
        return LocalMoveAction(distance=step.local_move.distance, angle=step.local_move.angle)
    if isinstance(step, CallStep):
        body = step.call.json_body
        return CallbackAction(url=step.call.url, method=step.call.method, data=body or {})
    assert isinstance(step, WaitStep), step
    return WaitReqAction()


def plan_offload(
    mission: Mission,
    *,
    targets: Sequence[NavPoint] = (),
    charge_pose: NavPoint | None = None,
) -> OffloadPlan:
    """``mission`` as one task chain; OffloadRejected naming every problem if it cannot be.

    ``targets``: the robot's targets, index = target id (goto steps); ``charge_pose``: the
    charger's pose (charge steps; None: a charge step is a problem).
    """
    problems = offload_problems(mission, targets=targets)
    chain, loop = _chain_steps(mission)
    if charge_pose is None:
        problems += [
            f"{_where(path, step)}: charge: the charger's pose is not known"
            for path, step in chain
            if isinstance(step, ChargeStep)
        ]
    if problems:
        raise OffloadRejected(mission.mission, problems)
    offloaded = tuple(
        OffloadedStep(
            path, step.name, step_action(step) or "?", _chain_action(step, targets, charge_pose)
        )
        for path, step in chain
    )
    count = None if loop is None else loop.loop.count
    looping = loop is not None and count != 1
    return OffloadPlan(mission.mission, offloaded, looping, count if looping else None)


# --- what the follower saw -----------------------------------------------------------


class ActionRun(BaseModel):
    """One run of one chain action as the follower saw it; times are its looks (loop s).

    ``loop`` counts passes from 1; ``state`` the last one seen (COMPLETE, ERROR, CANCELLED,
    or WORKING/PAUSED when the run's end was not seen); ``ended`` None while it runs.
    """

    model_config = ConfigDict(frozen=True)

    index: int = Field(ge=0, description="the action's place in the chain")
    loop: int = Field(ge=1)
    path: str
    name: str | None
    action: str = Field(description="the mission step's action key")
    type: str = Field(description="the chain's action type")
    state: str
    started: float
    ended: float | None = None


class OffloadReport(BaseModel):
    """How an offloaded mission ended, each action run the follower saw, the passes done."""

    model_config = ConfigDict(frozen=True)

    mission: str
    task_id: str
    ending: OffloadEnding
    state: str = Field(description="the task's last state seen")
    actions: list[ActionRun]
    loops_done: int = Field(0, ge=0)
    started: float
    ended: float
    error: str | None = None

    @property
    def completed(self) -> bool:
        """True when the chain ran to its end (and every counted pass)."""
        return self.ending == "completed"


@dataclass(frozen=True)
class ChainProgress:
    """An action of the chain started or ended (``run.ended`` set), at loop time ``at``."""

    mission: str
    at: float
    task_id: str
    state: str
    loops_done: int
    run: ActionRun


# --- following -----------------------------------------------------------------------


def _number(name: str, value: float, low: float) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise InvalidArgument(f"offload_mission: {name} must be a finite number, got {value!r}")
    if value < low or value <= 0:
        raise InvalidArgument(f"offload_mission: {name} must be at least {low:g}, got {value!r}")
    return float(value)


class _Follower:
    """Looks at one task once a period, keeps the runs seen, counts passes, ends the report."""

    def __init__(
        self,
        robot: Robot,
        http: HttpPart,
        plan: OffloadPlan,
        task_id: str,
        on_progress: Callable[[ChainProgress], None] | None,
        call_timeout: float,
    ) -> None:
        self.robot, self.http, self.plan, self.task_id = robot, http, plan, task_id
        self.on_progress = on_progress
        self.call_timeout = call_timeout
        self.loop = asyncio.get_running_loop()
        self.started = self.loop.time()
        self.runs: dict[tuple[int, int], ActionRun] = {}
        self.state = "WAITTING"
        self.loops_done = 0
        self.reached = False  # the counted passes are done: the host stopped the rest

    async def ask(self, call: Callable[[], Awaitable[_T]]) -> _T:
        with anyio.fail_after(self.call_timeout):
            return await call()

    def transient(self, exc: BaseException) -> bool:
        """A failed look worth trying again (the link, a timeout, the robot's 5xx)."""
        if self.robot.closed:
            return False
        if isinstance(exc, HttpError) and exc.status is not None and exc.status < 500:
            return False
        return isinstance(exc, (GalileoConnectionError, TimeoutError))

    def look(self, task: Task) -> None:
        """Record what ``task`` shows: runs started and ended, passes done."""
        now = self.loop.time()
        self.state = task.state
        done = task.loop_count
        self.loops_done = done if self.plan.count is None else min(done, self.plan.count)
        this_pass = done if task.state == "COMPLETE" else done + 1
        for (pass_no, index), run in list(self.runs.items()):
            if pass_no < this_pass and run.ended is None:  # its pass completed meanwhile
                self.update(run, "COMPLETE", now, pass_no, index)
        if self.plan.count is not None and this_pass > self.plan.count:
            return  # a pass past the count: the host stops it, it is no part of the plan
        for index, action in enumerate(task.sub_tasks[: len(self.plan.steps)]):
            if action.state == "WAITTING":
                continue
            seen = self.runs.get((this_pass, index))
            if seen is None:
                step = self.plan.steps[index]
                seen = ActionRun(
                    index=index, loop=this_pass, path=step.path, name=step.name,
                    action=step.action, type=action.type, state=action.state, started=now,
                )  # fmt: skip
                self.runs[(this_pass, index)] = seen
                self.emit(seen, now)
            if seen.ended is None:
                self.update(seen, action.state, now, this_pass, index)

    def update(self, run: ActionRun, state: str, now: float, pass_no: int, index: int) -> None:
        ended = now if state in TASK_ENDINGS else None
        if state == run.state and ended is None:
            return
        run = run.model_copy(update={"state": state, "ended": ended})
        self.runs[(pass_no, index)] = run
        if ended is not None:
            self.emit(run, now)

    def emit(self, run: ActionRun, now: float) -> None:
        if self.on_progress is None:
            return
        progress = ChainProgress(
            self.plan.name, now, self.task_id, self.state, self.loops_done, run
        )
        try:
            self.on_progress(progress)
        except Exception:  # as run_mission's: logged, the chain is followed on
            _log.exception("on_progress failed on %r", progress)

    async def count(self, task: Task) -> None:
        """Counted passes: no loop after the last pass begins; stopped if one more began."""
        count = self.plan.count
        if count is None or self.reached:
            return
        try:
            if task.loop_count == count - 1 and task.loop_flag:
                task = await self.ask(lambda: self.http.set_task_loop(self.task_id, False))
                self.look(task)
            if task.loop_count >= count and not task.ended:
                self.reached = True
                self.look(await self.ask(lambda: self.http.stop_task(self.task_id)))
        except (GalileoConnectionError, TimeoutError) as exc:
            if not self.transient(exc):
                raise  # the next look tries again otherwise

    async def follow(self, follow_timeout: float, period: float) -> OffloadReport:
        """Look once a ``period`` until the task ends, or nothing answers for follow_timeout."""
        last_answer = self.loop.time()
        wait = period
        while True:
            await asyncio.sleep(wait)
            try:
                task = await self.ask(lambda: self.http.get_task(self.task_id))
            except (GalileoConnectionError, TimeoutError) as exc:
                if isinstance(exc, HttpError) and exc.status == 404:
                    return self.report("failed", f"the robot no longer holds task {self.task_id}")
                if not self.transient(exc):
                    raise
                silent = self.loop.time() - last_answer
                if silent >= follow_timeout:
                    return self.report(
                        "link lost", f"no answer for {silent:.0f} s ({exc}); the chain goes on"
                    )
                wait = min(wait * 2, MAX_BACKOFF, follow_timeout - silent)
                _log.info("task %s: no answer (%s); next try in %.0f s", self.task_id, exc, wait)
                continue
            last_answer, wait = self.loop.time(), period
            self.look(task)
            if task.ended:
                return self.ending(task)
            await self.count(task)

    def ending(self, task: Task) -> OffloadReport:
        if task.state == "COMPLETE" or (task.state == "CANCELLED" and self.reached):
            return self.report("completed")
        if task.state == "CANCELLED":
            return self.report(
                "stopped", "the task was stopped (stop(), another client, or a goal by hand)"
            )
        failed = [i for i, action in enumerate(task.sub_tasks) if action.state == "ERROR"]
        if failed and failed[0] < len(self.plan.steps):
            step = self.plan.steps[failed[0]]
            where = _where(step.path, step)
            return self.report("failed", f"{where}: {step.chain_action.type} ended ERROR")
        return self.report("failed", "the task ended ERROR")

    def report(self, ending: OffloadEnding, error: str | None = None) -> OffloadReport:
        return OffloadReport(
            mission=self.plan.name, task_id=self.task_id, ending=ending, state=self.state,
            actions=sorted(self.runs.values(), key=lambda run: (run.loop, run.index)),
            loops_done=self.loops_done, started=self.started, ended=self.loop.time(),
            error=error,
        )  # fmt: skip


async def offload_mission(
    robot: Robot,
    mission: Mission,
    *,
    on_progress: Callable[[ChainProgress], None] | None = None,
    follow_timeout: float = FOLLOW_TIMEOUT,
    period: float = FOLLOW_PERIOD,
    call_timeout: float = CALL_TIMEOUT,
) -> OffloadReport:
    """Run ``mission`` as one task chain on the robot (http://) and follow it to its end.

    OffloadRejected (nothing sent but the questions) when a step cannot be offloaded or a
    goto's target does not exist; NotSupported on a link without the HTTP API. The task is
    looked at once a ``period`` (at least 1 s), each call within ``call_timeout`` s; a look
    that fails is tried again with back-off while the chain goes on, and after
    ``follow_timeout`` s without an answer the report ends "link lost". Counted loops are
    counted by this follower. Cancelled, or failing, once the task was started: robot.stop()
    stops the chain and the robot (shielded, within EXIT_STOP_TIMEOUT s), then it re-raises.
    """
    http = robot.http
    if http is None:
        raise NotSupported("offload_mission: the task chain needs an http:// or https:// link")
    period = _number("period", period, FOLLOW_PERIOD)
    follow_timeout = _number("follow_timeout", follow_timeout, 0.0)
    call_timeout = _number("call_timeout", call_timeout, 0.0)
    problems = offload_problems(mission)
    if problems:
        raise OffloadRejected(mission.mission, problems)
    steps = [step for _, step in _chain_steps(mission)[0]]
    plan = await _resolve(http, mission, steps, call_timeout)
    with anyio.fail_after(call_timeout):
        task = await http.create_task(plan.name, plan.actions, loop_flag=plan.loop_flag)
    follower = _Follower(robot, http, plan, task.id, on_progress, call_timeout)
    try:
        follower.look(await follower.ask(lambda: http.start_task(task.id)))
        return await follower.follow(follow_timeout, period)
    except BaseException:
        await exit_stop(robot, f"stopping task {task.id}")
        raise


async def _resolve(
    http: HttpPart, mission: Mission, steps: list[Any], call_timeout: float
) -> OffloadPlan:
    """Ask the robot what the plan needs: its targets (goto), its charger's pose (charge)."""
    targets: list[NavPoint] = []
    dock: NavPoint | None = None
    if any(isinstance(step, GotoStep) for step in steps):
        with anyio.fail_after(call_timeout):
            targets = await http.targets()
    if any(isinstance(step, ChargeStep) for step in steps):
        try:
            with anyio.fail_after(call_timeout):
                dock = await http.charge_pose()
        except HttpError as exc:
            if exc.status is None or exc.status >= 500:
                raise
            raise OffloadRejected(
                mission.mission, [f"charge: the robot does not tell its charger's pose ({exc})"]
            ) from None
    return plan_offload(mission, targets=targets, charge_pose=dock)
