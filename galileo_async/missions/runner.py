"""run_mission(): a Mission on a Robot, step by step, through the Robot's public calls.

Every goal goes through the Robot's one goal path (robot.goto, goto_point,
http.goto_pose): its progress checks, preemption and the user's stop. A user stop
(stop(), cancel(), stop_navigation(), zero_speed(), close(), another host's cancel or
goal) ends the mission at once: nothing is retried or skipped over. Cancelling the task
that runs the mission ends it too, the robot stopped on the way out.
"""

from __future__ import annotations

import asyncio
import logging
import math
from collections.abc import Awaitable, Callable, Mapping
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, NoReturn

import anyio
import anyio.lowlevel

from ..battery import battery_charge
from ..errors import (
    AcceptTimeout,
    CommandSuperseded,
    ConnectionLost,
    GalileoError,
    GalileoTimeout,
    GoalAborted,
    GoalCancelled,
    GoalRejected,
    GoalStalled,
    LinkStale,
    OperationFailed,
)
from ..models import ChargeStatus, GalileoStatus, LinkState
from ..robot.runtime import ROBOT_DEFAULT
from .calls import CallFailed, call_out
from .capabilities import capabilities_of, unreleased, unsupported
from .events import LoopStarted, MissionEnded, MissionEvent, StepEnded, StepStarted
from .exit_stop import exit_stop
from .journal import DEFAULT_JOURNAL_MAX_AGE, Journal, JournalRecord, ResumePoint, plan_hash
from .model import (
    ChargeUntil,
    LocalMove,
    LoopStep,
    Mission,
    step_action,
    step_paths,
)
from .report import MissionEnding, MissionRejected, MissionReport, StepEnding, StepReport
from .robot_api import MissionRobot

__all__ = [
    "CHARGE_TIMEOUT",
    "DEFAULT_JOURNAL_MAX_AGE",
    "LOCAL_MOVE_SPEED",
    "NAVIGATION_TIMEOUT",
    "Releases",
    "run_mission",
]

_log = logging.getLogger(__name__)

#: A release: called when a ``wait`` step starts; the step ends when the awaitable does.
Releases = Mapping[str, Callable[[], Awaitable[object]]]

#: Seconds a charge step (or a pause for a charge the robot began itself) waits at most.
CHARGE_TIMEOUT = 8 * 3600.0
#: Seconds for navigation to be ready again after a map switch.
NAVIGATION_TIMEOUT = 60.0
#: m/s of a local move's straight part (at most the Robot's speed limit).
LOCAL_MOVE_SPEED = 0.2
#: Metres within which a local move's distance counts as driven.
LOCAL_MOVE_TOLERANCE = 0.02

#: Steps that end themselves on a user stop (GoalCancelled, CommandSuperseded).
_SELF_STOPPING = frozenset({"goto", "goto_point", "goto_pose", "local_move"})
_GOALS = frozenset({"goto", "goto_point", "goto_pose"})
#: User stops that do not end a mission: a paused goal waits for resume().
_NOT_A_MISSION_STOP = frozenset({"pause()"})
#: The robot is on its way to, or on, the charger.
_CHARGING = (ChargeStatus.FINDING_DOCK, ChargeStatus.DOCKING, ChargeStatus.CHARGING)


class _Stopped(Exception):
    def __init__(self, by: str) -> None:
        super().__init__(by)
        self.by = by


class _Ended(Exception):
    def __init__(self, ending: MissionEnding, error: str) -> None:
        super().__init__(error)
        self.ending = ending
        self.error = error


class _Failure(Exception):
    def __init__(self, ending: StepEnding, error: str) -> None:
        super().__init__(error)
        self.ending = ending
        self.error = error


class _Again(Exception):
    """Run the step again without using a retry (the link is back; a charge is over)."""


class _Jump(Exception):
    def __init__(self, name: str) -> None:
        super().__init__(name)
        self.name = name


async def run_mission(
    robot: MissionRobot,
    mission: Mission,
    *,
    releases: Releases | None = None,
    journal: str | Path | None = None,
    resume: bool = False,
    on_progress: Callable[[MissionEvent], None] | None = None,
    http_client: Any = None,
    journal_max_age: float = DEFAULT_JOURNAL_MAX_AGE,
) -> MissionReport:
    """Run ``mission`` on ``robot``; its MissionReport once it completed, stopped or failed.

    Checked first, nothing sent: MissionRejected naming every problem (a step the link
    cannot run, a ``wait`` whose release is not in ``releases``, a journal that does not
    match with ``resume``). ``journal``: a file where the run is recorded at each step;
    ``resume``: start where the journal says the last run was (no file: at the start).
    ``on_progress(event)``: called synchronously with each MissionEvent (one that raises
    is logged, the run goes on). ``http_client``:
    an aiohttp.ClientSession for call steps (None: one per call). Cancelling the caller
    ends the mission, the robot stopped (bounded), and raises the cancellation.
    """
    run = _Run(robot, mission, dict(releases or {}), on_progress, http_client)
    point = run.check(journal, resume=resume, max_age=journal_max_age)
    return await run.run(point)


class _Run:
    """One run of a mission: its position, its report, what it listens to on the Robot."""

    def __init__(
        self,
        robot: MissionRobot,
        mission: Mission,
        releases: dict[str, Callable[[], Awaitable[object]]],
        on_progress: Callable[[MissionEvent], None] | None,
        http_client: Any,
    ) -> None:
        self.robot = robot
        self.mission = mission
        self.releases = releases
        self.on_progress = on_progress
        self.http_client = http_client
        self.journal: Journal | None = None
        self.plan = plan_hash(mission)
        self.paths = {step.name: path for path, step in step_paths(mission.steps) if step.name}
        self.counters: dict[str, int] = {}
        self.steps: list[StepReport] = []
        self.loops_done = 0
        self.stopped_by: str | None = None
        self.scope: anyio.CancelScope | None = None
        self.odometer = 0.0
        self.last_pose: tuple[float, float] | None = None
        self.own_charge = False

    # --- before anything moves ----------------------------------------------------------

    def check(
        self, journal: str | Path | None, *, resume: bool, max_age: float
    ) -> ResumePoint | None:
        """The point to start at; MissionRejected naming every problem."""
        problems = [str(step) for step in unsupported(self.mission, capabilities_of(self.robot))]
        for path, step in unreleased(self.mission, self.releases):
            problems.append(f"{path}: no release {step.wait.release!r} was given")
        point = None
        if journal is not None:
            self.journal = Journal(journal)
            if not self.journal.path.parent.is_dir():
                problems.append(f"journal {journal}: no folder {self.journal.path.parent}")
            if resume:
                try:
                    point = self.journal.resume_point(self.mission, max_age=max_age)
                except MissionRejected as exc:
                    problems.extend(exc.problems)
        elif resume:
            problems.append("resume needs a journal")
        if problems:
            raise MissionRejected(self.mission.mission, problems)
        return point

    # --- the run ------------------------------------------------------------------------

    async def run(self, point: ResumePoint | None) -> MissionReport:
        loop = asyncio.get_running_loop()
        started, started_at = loop.time(), _now()
        ending: MissionEnding = "completed"
        error: str | None = None
        self.robot.add_stop_listener(self._user_stop)
        self.robot.add_update_listener(self._moved)
        try:
            try:
                await self._run_all(point)
            except _Stopped as stop:
                ending, error = "stopped", f"stopped by {stop.by}"
            except _Ended as end:
                ending, error = end.ending, end.error
            except BaseException as exc:  # cancelled, or a bug: stop the robot, then raise
                cancelled = isinstance(exc, asyncio.CancelledError)
                ending = "cancelled" if cancelled else "failed"
                try:
                    self._finish(started, started_at, ending, _text(exc), point)
                finally:
                    await self._exit_stop()
                raise
        finally:
            self.robot.remove_stop_listener(self._user_stop)
            self.robot.remove_update_listener(self._moved)
        report = self._finish(started, started_at, ending, error, point)
        if ending == "stopped" and self.stopped_by not in ("stop()", "close()"):
            await self._exit_stop()
        return report

    def _finish(
        self,
        started: float,
        started_at: datetime,
        ending: MissionEnding,
        error: str | None,
        point: ResumePoint | None,
    ) -> MissionReport:
        report = MissionReport(
            mission=self.mission.mission,
            ending=ending,
            steps=list(self.steps),
            started=started,
            ended=asyncio.get_running_loop().time(),
            started_at=started_at,
            ended_at=_now(),
            loops_done=self.loops_done,
            stopped_by=self.stopped_by,
            error=error,
            resumed_at=None if point is None else point.path,
        )
        last = self.steps[-1].path if self.steps else None
        self._record(ending, last)
        self._emit(MissionEnded(self.mission.mission, report.ended, report))
        return report

    async def _exit_stop(self) -> None:
        """Stop the robot, shielded and bounded (exit_stop)."""
        await exit_stop(self.robot, "the mission's exit stop")

    # --- what the Robot tells the run ---------------------------------------------------

    def _user_stop(self, name: str) -> None:
        if name in _NOT_A_MISSION_STOP or self.stopped_by is not None:
            return
        self.stopped_by = name
        if self.scope is not None:
            self.scope.cancel()

    def _moved(self, status: GalileoStatus) -> None:
        if status.charge_status == ChargeStatus.FREE:
            self.own_charge = False  # the mission's own charge is over once off the charger
        pose = status.pose
        if pose is None:
            return
        if self.last_pose is not None:
            self.odometer += math.hypot(pose.x - self.last_pose[0], pose.y - self.last_pose[1])
        self.last_pose = (pose.x, pose.y)

    def _emit(self, event: MissionEvent) -> None:
        if self.on_progress is not None:
            try:
                self.on_progress(event)
            except Exception:  # as the Robot's listeners: logged, the run goes on
                _log.exception("on_progress failed on %r", event)

    def _record(self, state: str, path: str | None) -> None:
        if self.journal is not None:
            self.journal.write(
                JournalRecord(
                    mission=self.mission.mission,
                    plan=self.plan,
                    state=state,
                    path=path,
                    loops=dict(self.counters),
                    at=_wall(),
                )
            )

    # --- walking the plan ---------------------------------------------------------------

    async def _run_all(self, point: ResumePoint | None) -> None:
        address: tuple[int, ...] = () if point is None else point.address
        after = point is not None and point.after
        if point is not None:
            self.counters = dict(point.loops)
        while True:
            try:
                await self._run_steps(self.mission.steps, "steps", address, after)
                return
            except _Jump as jump:
                path = self.paths[jump.name]
                address, after = _address(path), False
                self.counters = {
                    loop: n for loop, n in self.counters.items() if path.startswith(loop + ".")
                }

    async def _run_steps(
        self, steps: list[Any], prefix: str, address: tuple[int, ...], after: bool
    ) -> None:
        start = address[0] if address else 0
        inner, inner_after = (address[1:], after) if len(address) > 1 else ((), False)
        if len(address) == 1 and after:
            start += 1
        for index in range(start, len(steps)):
            step, path = steps[index], f"{prefix}[{index}]"
            sub, sub_after = (inner, inner_after) if index == start else ((), False)
            if isinstance(step, LoopStep):
                await self._run_loop(step, path, sub, sub_after)
            else:
                await self._run_step(step, path)

    async def _run_loop(
        self, step: LoopStep, path: str, inner: tuple[int, ...], after: bool
    ) -> None:
        count = step.loop.count
        done = self.counters.get(path, 0)
        while count is None or done < count:
            self.counters[path] = done
            now = asyncio.get_running_loop().time()
            self._emit(LoopStarted(self.mission.mission, now, path, step.name, done + 1, count))
            await self._run_steps(step.loop.steps, f"{path}.loop.steps", inner, after)
            inner, after = (), False
            done += 1
            self.loops_done += 1
            await anyio.lowlevel.checkpoint()  # a loop of instant steps still lets a stop in
        self.counters.pop(path, None)

    async def _run_step(self, step: Any, path: str) -> None:
        loop = asyncio.get_running_loop()
        action = step_action(step) or "?"
        started, started_at, odometer = loop.time(), _now(), self.odometer
        loops = {key: n + 1 for key, n in self.counters.items()}
        attempts, retries = 0, step.on_failure.retry
        ending: StepEnding = "reached" if action in _GOALS else "done"
        error: str | None = None

        def report(ending: StepEnding, error: str | None) -> None:
            self.steps.append(
                StepReport(
                    path=path,
                    name=step.name,
                    action=action,
                    ending=ending,
                    started=started,
                    ended=loop.time(),
                    started_at=started_at,
                    ended_at=_now(),
                    attempts=max(1, attempts),
                    distance_m=round(self.odometer - odometer, 3),
                    loops=loops,
                    error=error,
                )
            )
            self._record("ended", path)
            self._emit(StepEnded(self.mission.mission, loop.time(), self.steps[-1]))

        try:
            while True:
                attempts += 1
                self._record("started", path)
                self._emit(
                    StepStarted(
                        self.mission.mission, loop.time(), path, step.name, action, attempts, loops
                    )
                )
                try:
                    await self._attempt(step, action)
                    break
                except _Again:
                    continue
                except _Failure as failure:
                    if retries > 0:
                        retries -= 1
                        continue
                    ending, error = failure.ending, failure.error
                    break
        except _Stopped as stop:
            report("stopped", f"stopped by {stop.by}")
            raise
        except _Ended as end:
            report("link lost" if end.ending == "link lost" else "failed", end.error)
            raise
        except BaseException as exc:
            report("cancelled" if isinstance(exc, asyncio.CancelledError) else "failed", _text(exc))
            raise
        then = step.on_failure.then
        if error is None or then == "skip":
            report(ending if error is None else "skipped", error)
            return
        report(ending, error)
        if then == "goto":
            raise _Jump(step.on_failure.goto)
        raise _Ended("failed", f"{path}: {error}")

    # --- one attempt ----------------------------------------------------------------------

    async def _attempt(self, step: Any, action: str) -> None:
        """Run ``step`` once; _Failure, _Again, _Stopped or _Ended when it did not do it."""
        self._go_on()
        if action in _SELF_STOPPING:
            await self._pause_while_charging()
        try:
            if action in _SELF_STOPPING:
                self._go_on()  # a stop during the pause: no motion after it
                await self._motion(step, action)
            else:
                await self._stoppable(self._do(step, action), step.timeout)
        except (GoalCancelled, CommandSuperseded) as exc:
            by = self.stopped_by or _stopped_by(exc)
            status = self.robot.status
            if by is None and status is not None and status.charge_status in _CHARGING:
                raise _Again from None  # the robot went to charge: _pause_while_charging
            self.stopped_by = self.stopped_by or by or "another host"
            raise _Stopped(self.stopped_by) from None
        except (ConnectionLost, LinkStale) as exc:
            await self._link_lost(exc)
        except GoalStalled as exc:
            raise _Failure("stalled", str(exc)) from None
        except (GoalRejected, AcceptTimeout) as exc:
            raise _Failure("rejected", str(exc)) from None
        except GoalAborted as exc:
            raise _Failure("aborted", str(exc)) from None
        except TimeoutError as exc:
            raise _Failure("timeout", str(exc) or f"timed out after {step.timeout} s") from None
        except (GalileoError, CallFailed) as exc:
            raise _Failure("failed", str(exc)) from None
        self._go_on()

    def _go_on(self) -> None:
        """Raise _Stopped once a user stop has ended the mission: nothing moves after it."""
        if self.stopped_by is not None:
            raise _Stopped(self.stopped_by)

    async def _stoppable(self, work: Awaitable[None], seconds: float | None) -> None:
        """Await ``work`` within ``seconds``; a user stop meanwhile cancels it: _Stopped."""
        with anyio.CancelScope() as scope:
            self.scope = scope
            try:
                with anyio.fail_after(seconds):
                    await work
            finally:
                self.scope = None
        if scope.cancelled_caught:
            raise _Stopped(self.stopped_by or "a user stop")
        self._go_on()  # a stop as the work ended delivers no cancellation

    async def _link_lost(self, exc: GalileoError) -> NoReturn:
        policy = self.mission.on_link_loss
        if policy.then == "abort":
            raise _Ended("link lost", str(exc))
        try:
            await self._stoppable(self._wait_link(policy.wait), None)
        except (GalileoTimeout, ConnectionLost):
            raise _Ended("link lost", f"{exc}; not back within {policy.wait:g} s") from None
        raise _Again

    async def _wait_link(self, seconds: float) -> None:
        await self.robot.wait_link(LinkState.UP, timeout=seconds)

    async def _pause_while_charging(self) -> None:
        """A charge the robot began itself (a low battery): wait until it is over."""
        status = self.robot.status
        if status is None or status.charge_status not in _CHARGING or self.own_charge:
            return
        await self._stoppable(self._until_charged(), None)

    async def _until_charged(self) -> None:
        await self.robot.wait_until(lambda s: s.charge_status not in _CHARGING, CHARGE_TIMEOUT)

    # --- the steps ----------------------------------------------------------------------

    async def _motion(self, step: Any, action: str) -> None:
        robot = self.robot
        timeout = ROBOT_DEFAULT if step.timeout is None else step.timeout
        if action == "goto":
            await robot.goto(step.goto, timeout=timeout)
        elif action == "goto_point":
            await robot.goto_point(step.goto_point.x, step.goto_point.y, timeout=timeout)
        elif action == "goto_pose":
            pose = step.goto_pose
            assert robot.http is not None  # checked before the run
            await robot.http.goto_pose(pose.x, pose.y, pose.theta, timeout=timeout)
        else:
            with anyio.fail_after(step.timeout):
                await self._local_move(step.local_move)

    async def _do(self, step: Any, action: str) -> None:
        robot, http = self.robot, self.robot.http
        if action == "dwell":
            await anyio.sleep(step.dwell)
        elif action == "wait":
            name = step.wait.release
            with anyio.fail_after(step.wait.timeout):
                try:
                    await self.releases[name]()
                except Exception as exc:  # the caller's release failed: the step did
                    raise _Failure("failed", f"release {name!r}: {_text(exc)}") from None
        elif action == "call":
            await call_out(step.call, self.http_client)
        elif action == "charge":
            await self._charge(step.charge)
        elif action == "say":
            assert http is not None  # checked before the run
            await http.say(step.say)
        elif action == "switch_map":
            assert http is not None
            await http.switch_map(step.switch_map.map, step.switch_map.path)
            status = robot.status
            if status is None or not status.navigating:
                await robot.start_navigation(timeout=NAVIGATION_TIMEOUT)
            await robot.wait_until(_goal_ready, NAVIGATION_TIMEOUT)
        else:
            raise _Failure("failed", f"no such step: {action}")

    async def _charge(self, until: ChargeUntil) -> None:
        """Dock and charge; wait for the level asked for (none: until charging)."""
        robot = self.robot
        self.own_charge = True
        status = robot.status
        if status is None or status.charge_status not in (*_CHARGING, ChargeStatus.CHARGED):
            await robot.start_charging()

        def enough(status: GalileoStatus) -> bool:
            if status.charge_status == ChargeStatus.ERROR:
                return True
            if not status.charging or status.power is None:
                return False
            if until.until_percent is not None:
                return battery_charge(status.power) >= until.until_percent
            if until.until_volts is not None:
                return status.power >= until.until_volts
            return True

        status = await robot.wait_until(enough, CHARGE_TIMEOUT)
        if status.charge_status == ChargeStatus.ERROR:
            raise OperationFailed("charging failed: the robot shows a charging error", status)

    async def _local_move(self, move: LocalMove) -> None:
        """Turn by ``angle``, then drive ``distance`` (measured from the pose) and stop."""
        robot = self.robot
        if move.angle:
            pose = _pose(robot)
            heading = math.degrees(math.remainder(pose[2] + move.angle, math.tau))
            await robot.turn_to(heading)
        if not move.distance:
            return
        self._go_on()  # a stop as the turn ended: no drive after it
        x0, y0, _ = _pose(robot)
        speed = math.copysign(min(LOCAL_MOVE_SPEED, robot.speed_limits.linear), move.distance)
        goal = abs(move.distance) - LOCAL_MOVE_TOLERANCE
        async with robot.drive(speed, 0.0):
            await robot.wait_until(
                lambda s: s.pose is not None and math.hypot(s.pose.x - x0, s.pose.y - y0) >= goal,
                None,
            )


def _stopped_by(exc: GoalCancelled | CommandSuperseded) -> str | None:
    if isinstance(exc, CommandSuperseded):
        return exc.superseded_by
    if exc.cancelled_by is not None:
        return exc.cancelled_by
    return "another goal" if exc.preempted else None


def _pose(robot: MissionRobot) -> tuple[float, float, float]:
    status = robot.status
    pose = None if status is None else status.pose
    if pose is None:
        raise OperationFailed("local_move: the robot's pose is unknown", status)
    return pose.x, pose.y, pose.theta


def _goal_ready(status: GalileoStatus) -> bool:
    return status.navigating and status.visual_initialised


def _address(path: str) -> tuple[int, ...]:
    return tuple(int(part.split("[")[1].rstrip("]")) for part in path.split(".") if "[" in part)


def _text(exc: BaseException) -> str:
    if isinstance(exc, asyncio.CancelledError):
        return "cancelled"
    return f"{type(exc).__name__}: {exc}" if str(exc) else type(exc).__name__


def _now() -> datetime:
    return datetime.now(timezone.utc)


def _wall() -> float:
    return _now().timestamp()
