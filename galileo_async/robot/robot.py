"""Robot: awaitable operations with preconditions, busy back-off and confirmation, each
defined here and carried out by the part of its concern."""

from __future__ import annotations

import asyncio
from collections.abc import AsyncIterator, Awaitable, Callable
from collections.abc import Mapping as AbcMapping
from pathlib import Path
from types import TracebackType
from typing import TYPE_CHECKING

from .._checks import check_bool, check_timeout
from ..errors import CommandSuperseded, GalileoTimeout, InvalidArgument, UnconfirmedOperation
from ..events import Event
from ..models import ChargeStatus, GalileoStatus
from ..options import (
    DEFAULT_ACCEPT_TIMEOUT,
    DEFAULT_ANGLE_TOLERANCE,
    DEFAULT_GOAL_TIMEOUT,
    DEFAULT_WAIT_TIMEOUT,
)
from ..protocol import (
    AddTarget,
    ApiCall,
    Backward,
    Command,
    Forward,
    Goto,
    PoseGoal,
    ShutdownHost,
    StartNavigation,
    Stop,
    StopNavigation,
    TurnLeft,
    TurnRight,
    Velocity,
)
from ..state.listeners import EventListener, StatusListener
from ..state.store import StatusStore, StatusStream
from ..transitions import DEFAULT_ARRIVE_TOLERANCE
from ..transports import Link, LinkState, LinkStats
from ..transports.follow import LinkStateStream
from .drive import (
    DEFAULT_DRIVE_RATE,
    DEFAULT_MAX_ANGULAR_SPEED,
    DEFAULT_MAX_LINEAR_SPEED,
    DriveSession,
    SpeedLimits,
)
from .goal import GoalResult, GoalRunner
from .http_part import HttpPart
from .operations import (
    CANCEL_SEND_TIMEOUT,
    DEFAULT_TIMEOUT,
    GOAL_READY,
    NAVIGATING,
    NOT_NAVIGATING,
    Confirm,
    Operations,
    Require,
)
from .options import check_robot_options
from .progress import DEFAULT_PROGRESS_TIMEOUT
from .runtime import (
    OPEN_ROBOTS,
    ROBOT_DEFAULT,
    Deadline,
    RobotDefault,
    finish_shielded,
    or_default,
)
from .services import Charging, Mapping, Patrol
from .stopping import DEFAULT_STOP_TIMEOUT, StopReport, stop_motion
from .supersede import goal_superseded
from .targets import DynamicTargets, landed_at
from .turn import ROTATE_TIMEOUT, rotate, turn_in_place

if TYPE_CHECKING:
    from ..missions.events import MissionEvent
    from ..missions.model import Mission
    from ..missions.report import MissionReport

__all__ = [
    "DEFAULT_ACCEPT_TIMEOUT",
    "DEFAULT_ANGLE_TOLERANCE",
    "DEFAULT_ARRIVE_TOLERANCE",
    "DEFAULT_GOAL_TIMEOUT",
    "DEFAULT_PROGRESS_TIMEOUT",
    "DEFAULT_TIMEOUT",
    "DEFAULT_WAIT_TIMEOUT",
    "NAVIGATION_TIMEOUT",
    "ROBOT_DEFAULT",
    "ROTATE_TIMEOUT",
    "GoalResult",
    "Robot",
    "RobotDefault",
]

#: Seconds for navigation to open and the visual system to initialise.
NAVIGATION_TIMEOUT = 60.0


_NOT_MAPPING = Require(lambda s: not s.mapping, "the robot is building a map")


class Robot:
    """A connected Galileo robot; every method validates, then sends through Operations.send.

    Composed by concern, not stacked: it holds an Operations (preconditions, the one send,
    the user's stops), a GoalRunner (goals), the DynamicTargets and the Patrol, Mapping and
    Charging parts, each made on that Operations; turning (turn.py) and stop() (stopping.py)
    are functions of it. Each public method is defined here and delegates to one of them;
    ``http`` (an HttpPart) is what only the HTTP API does, None off http(s)://.
    """

    def __init__(
        self,
        link: Link,
        store: StatusStore,
        *,
        map_targets: int | None = None,
        accept_timeout: float = DEFAULT_ACCEPT_TIMEOUT,
        arrive_tolerance: float = DEFAULT_ARRIVE_TOLERANCE,
        goal_timeout: float | None = DEFAULT_GOAL_TIMEOUT,
        wait_timeout: float | None = DEFAULT_WAIT_TIMEOUT,
        progress_timeout: float | None = DEFAULT_PROGRESS_TIMEOUT,
        angle_tolerance: float = DEFAULT_ANGLE_TOLERANCE,
        max_linear_speed: float = DEFAULT_MAX_LINEAR_SPEED,
        max_angular_speed: float = DEFAULT_MAX_ANGULAR_SPEED,
    ) -> None:
        check_robot_options(
            {
                "angle_tolerance": angle_tolerance,
                "max_linear_speed": max_linear_speed,
                "max_angular_speed": max_angular_speed,
                "map_targets": map_targets,
                "accept_timeout": accept_timeout,
                "arrive_tolerance": arrive_tolerance,
                "goal_timeout": goal_timeout,
                "wait_timeout": wait_timeout,
                "progress_timeout": progress_timeout,
            }
        )
        self._link, self._store = link, store
        self._ops = ops = Operations(link, store)
        self._goals = GoalRunner(ops)
        self._targets = DynamicTargets(ops, map_targets)
        self._patrol, self._mapping, self._charging = Patrol(ops), Mapping(ops), Charging(ops)
        self.http: HttpPart | None = (
            HttpPart(ops, self._goto) if link.capabilities.rest_api else None
        )
        #: Awaited first on close: what serves this Robot to others (the control socket).
        self._closers: list[Callable[[], Awaitable[None]]] = []
        OPEN_ROBOTS.add(self)
        self.accept_timeout = float(accept_timeout)
        self.arrive_tolerance = float(arrive_tolerance)
        #: Default ``timeout`` of goto/goto_point and of wait_until (None: no limit).
        self.goal_timeout = goal_timeout
        self.wait_timeout = wait_timeout
        #: Default ``progress_timeout`` of goto/goto_point (None: never stalled).
        self.progress_timeout = progress_timeout
        #: rotate_to and turn_to within this many degrees of the heading: done, nothing sent.
        self.angle_tolerance = float(angle_tolerance)
        #: Speeds at 100 % of the serial speed commands (drive() converts to percentages).
        self.speed_limits = SpeedLimits(float(max_linear_speed), float(max_angular_speed))
        self._close_task: asyncio.Task[None] | None = None

    # --- state -----------------------------------------------------------------------

    @property
    def status(self) -> GalileoStatus | None:
        """The latest status of the robot, or None before its first (placeholders are not one)."""
        return self._store.status

    @property
    def awaiting_robot(self) -> bool:
        """True while the link is up but the serial node sends only placeholder frames.

        The vendor's serial node sends its defaults until the navigation system's first
        status reaches it, and again after it restarts; ``status`` is None meanwhile.
        """
        return self._store.awaiting_robot

    @property
    def link(self) -> LinkStats:
        """The link's statistics (a LinkStats), not the link: frames, bytes, discards, lost
        frames, reconnects, layout, and ``state`` (also ``link_state``)."""
        return self._link.stats

    @property
    def closed(self) -> bool:
        """True once close() was called."""
        return self._ops.closed

    @property
    def map_targets(self) -> int | None:
        """How many targets the robot's map has (goto_point and add_target need it)."""
        return self._targets.map_targets

    @map_targets.setter
    def map_targets(self, value: int | None) -> None:
        self._targets.map_targets = value

    async def wait_until(
        self,
        predicate: Callable[[GalileoStatus], bool],
        timeout: float | RobotDefault | None = ROBOT_DEFAULT,
    ) -> GalileoStatus:
        """First status (the latest included) where ``predicate`` holds; within ``wait_timeout``.

        Left out, ``timeout`` is the Robot's ``wait_timeout`` (30 s unless set); None: no limit.
        """
        if not callable(predicate):
            raise InvalidArgument(f"predicate must be a function of a status, got {predicate!r}")
        seconds = or_default(timeout, self.wait_timeout)
        check_timeout("timeout", seconds)
        self._ops.ensure_loop()
        return await self._store.wait_until(predicate, seconds)

    def statuses(self) -> StatusStream:
        """Iterate over statuses, newest only: a slow consumer skips to the latest."""
        self._ops.ensure_loop()
        return self._store.statuses()

    def events(self) -> AsyncIterator[Event]:
        """Iterate over typed transition events (goal reached, visual lost, link stale …)."""
        self._ops.ensure_loop()
        return self._store.events()

    # --- link state and listeners ----------------------------------------------------

    @property
    def link_state(self) -> LinkState:
        """Where the link is now: CONNECTING, UP, STALE, LOST or CLOSED (the link keeps it)."""
        return self._link.state

    def link_states(self) -> LinkStateStream:
        """Async iterator of the link's state: the state now, then each change; ends after CLOSED.

        Every change is kept (an outage is UP → STALE → LOST → UP); leaving the loop, or
        cancelling the task in it, stops following.
        """
        self._ops.ensure_loop()
        return self._link.states()

    async def wait_link(
        self, *states: LinkState, timeout: float | RobotDefault | None = ROBOT_DEFAULT
    ) -> LinkState:
        """Return the first of ``states`` the link is in, now or later.

        Left out, ``timeout`` is the Robot's ``wait_timeout``; None: no limit. GalileoTimeout
        after it; ConnectionLost once the link closes (unless CLOSED is one of ``states``);
        InvalidArgument for no state or one that is not a LinkState.
        """
        if not states or not all(isinstance(state, LinkState) for state in states):
            raise InvalidArgument(f"wait_link takes one or more LinkState, got {states!r}")
        seconds = or_default(timeout, self.wait_timeout)
        check_timeout("timeout", seconds)
        self._ops.ensure_loop()
        return await self._link.wait_state(*states, timeout=seconds)

    def add_update_listener(self, listener: StatusListener) -> None:
        """Call ``listener(status)`` with every later status, synchronously (keep it cheap).

        Any number of listeners; a listener that raises is logged, the others still run.
        """
        self._store.add_update_listener(listener)

    def remove_update_listener(self, listener: StatusListener) -> None:
        """Stop calling ``listener`` (no-op if it is not one)."""
        self._store.remove_update_listener(listener)

    def add_event_listener(self, listener: EventListener) -> None:
        """Call ``listener(event)`` with every later event, synchronously (keep it cheap)."""
        self._store.add_event_listener(listener)

    def remove_event_listener(self, listener: EventListener) -> None:
        """Stop calling ``listener`` (no-op if it is not one)."""
        self._store.remove_event_listener(listener)

    def add_raw_listener(self, listener: Callable[[bytes], None]) -> bool:
        """Call ``listener(data)`` with every read's bytes as they came off the link.

        Synchronously, before they are decoded (keep it cheap); True on links that carry
        the serial protocol's bytes (serial, socket://, sim://), False (never called) on
        udp://, http:// and ros://.
        """
        return self._link.channel.add_raw_listener(listener)

    def remove_raw_listener(self, listener: Callable[[bytes], None]) -> None:
        """Stop calling ``listener`` (no-op if it is not one)."""
        self._link.channel.remove_raw_listener(listener)

    def add_stop_listener(self, listener: Callable[[str], None]) -> None:
        """Call ``listener(name)`` after every user stop of this Robot, synchronously.

        ``name`` is the stop's: "stop()", "cancel()", "pause()", "stop_navigation()",
        "zero_speed()" or "close()". A listener that raises is logged, the others still run.
        """
        self._ops.supersession.stop_listeners.append(listener)

    def remove_stop_listener(self, listener: Callable[[str], None]) -> None:
        """Stop calling ``listener`` (no-op if it is not one)."""
        listeners = self._ops.supersession.stop_listeners
        if listener in listeners:
            listeners.remove(listener)

    # --- sending ---------------------------------------------------------------------

    async def send(self, command: Command, *, timeout: float | None = DEFAULT_TIMEOUT) -> None:
        """Send any command object as is, after busy back-off; nothing is confirmed."""
        if not isinstance(command, Command):
            raise InvalidArgument(f"expected a protocol command object, got {command!r}")
        if isinstance(command, Velocity) and not self._link.capabilities.velocity:
            raise InvalidArgument("a Velocity goes over ros:// only; use drive() on this link")
        if isinstance(command, PoseGoal) and not self._link.capabilities.pose_goals:
            raise InvalidArgument("a PoseGoal goes over http:// only; use goto_point()")
        if isinstance(command, ApiCall) and not self._link.capabilities.rest_api:
            raise InvalidArgument("an ApiCall goes over http:// only (robot.http is None here)")
        await self._ops.send_unconfirmed(command, f"send({command!r})", timeout)

    def drive(
        self, linear: float = 0.0, angular: float = 0.0, *, rate: float = DEFAULT_DRIVE_RATE
    ) -> DriveSession:
        """Velocity control: ``async with robot.drive(0.3, 0.0) as d: d.set(angular=0.5)``.

        ``linear`` m/s (forward positive) and ``angular`` rad/s (left positive), within
        ``speed_limits``; re-sent every 1/``rate`` s (2-20 Hz) while inside, from the
        session's own task; one stop is written when the block is left, whatever way.
        InvalidArgument (bad value) at once; NotReady on entering while a goal is working
        or paused, or another drive session is active. A goal, goto_point or start_patrol
        inside is NotReady. On serial links the speeds become f/b and c/d percentages
        (protocol.speed_commands); on ros:// a geometry_msgs/Twist on /cmd_vel.
        """
        self._ops.ensure_loop()
        slot = self._ops.supersession.drive
        return DriveSession(self._ops, self.speed_limits, linear, angular, rate, slot)

    # --- velocity and stopping ----------------------------------------------------------

    # One command each: 22 chassis builds hold it until the next, others stop 1-3 s after
    # it (docs/protocol.md §6.5); drive() keeps a speed alive and always ends with a stop.

    async def forward(self, percent: int, *, timeout: float | None = DEFAULT_TIMEOUT) -> None:
        """Write ``f`` once at ``percent`` (0-100) of max speed; the chassis decides how long."""
        await self._ops.send_unconfirmed(Forward(percent), "forward", timeout)

    async def backward(self, percent: int, *, timeout: float | None = DEFAULT_TIMEOUT) -> None:
        """Write ``b`` once at ``percent`` (0-100) of max speed; as forward()."""
        await self._ops.send_unconfirmed(Backward(percent), "backward", timeout)

    async def turn_left(self, percent: int, *, timeout: float | None = DEFAULT_TIMEOUT) -> None:
        """Write ``c`` once at ``percent`` (0-100) of max angular speed; as forward()."""
        await self._ops.send_unconfirmed(TurnLeft(percent), "turn_left", timeout)

    async def turn_right(self, percent: int, *, timeout: float | None = DEFAULT_TIMEOUT) -> None:
        """Write ``d`` once at ``percent`` (0-100) of max angular speed; as forward()."""
        await self._ops.send_unconfirmed(TurnRight(percent), "turn_right", timeout)

    async def zero_speed(self, brake: int = 100) -> None:
        """Write one ``Stop(brake)`` (both speeds 0); a goal or patrol drives on. Use stop().

        Sent at once, even while busy or stale; a user stop: a drive or goal command called
        before it that still waits is never written (Supersession.user_stopped).
        """
        command = Stop(brake)
        self._ops.user_stopped("zero_speed()")
        await self._ops.send(command, what="zero_speed", even_stale=True)

    async def stop(
        self, brake: int = 100, *, timeout: float | None = DEFAULT_STOP_TIMEOUT
    ) -> StopReport:
        """Halt every motion, whoever started it; return once the status shows it stopped.

        Ends this Robot's drive()/turn_to() sessions and every call of it awaiting motion
        at once (goto, goto_point, goto_pose: GoalCancelled; rotate_to, turn_to: CommandSuperseded;
        each naming "stop()"), then writes, even while busy or stale: ``m 6`` (stop patrol)
        unless the status shows none, ``i 2`` (cancel the goal; on http:// the nav task), and
        a stop of both speeds with ``brake`` (0-100); on http:// each task chain this Robot
        started is stopped first (GET /task/stop) and, after the rest, every other task the
        robot shows WORKING or PAUSED (StopReport.chains). Returns a StopReport once a status shows
        no goal working or paused, no patrol and no speed (a layout without speeds, UDP,
        cannot show one); StopUnconfirmed naming each part still shown after ``timeout`` s,
        or at once on a stale link. ConnectionLost: the link is lost and nothing was sent.
        """
        command = Stop(brake)
        check_timeout("timeout", timeout)
        ops = self._ops
        ops.ensure_open()
        drive, goal = ops.supersession.drive.active, self._goals.running
        ops.user_stopped("stop()")
        self._goals.cancelling()  # the running goal's end is a cancel, not a planner abort
        tasks = ops.supersession.halt_motions("stop()")
        chains = None if self.http is None else self.http.started_tasks
        return await stop_motion(
            ops, command, timeout, goal=goal, drive=drive, tasks=tasks, chains=chains
        )

    # --- navigation --------------------------------------------------------------------

    async def start_navigation(self, *, timeout: float | None = NAVIGATION_TIMEOUT) -> None:
        """Open navigation; return once it is open and the visual system is initialised."""
        check_timeout("timeout", timeout)
        what = "start_navigation"
        deadline = Deadline(timeout)
        await self._ops.send(
            StartNavigation(), what=what, deadline=deadline, require=_NOT_MAPPING,
            unless=NAVIGATING.holds,
            then=Confirm(
                NAVIGATING.holds, field="nav_status",
                hint="; the firmware ignores a start within 5-30 s of the previous one",
            ),
        )  # fmt: skip
        try:
            await self._store.wait_until(GOAL_READY.holds, timeout=deadline.remaining())
        except GalileoTimeout as exc:
            raise UnconfirmedOperation(
                f"{what}: navigation is open but the visual system did not initialise "
                f"within {timeout} s",
                exc.status,
            ) from None

    async def stop_navigation(self, *, timeout: float | None = DEFAULT_TIMEOUT) -> None:
        """Stop navigation (also patrol and the goal); return once it is closed (a user stop)."""
        self._ops.user_stopped("stop_navigation()")
        check_timeout("timeout", timeout)
        await self._ops.send(
            StopNavigation(), what="stop_navigation", deadline=Deadline(timeout),
            unless=NOT_NAVIGATING.holds, then=Confirm(NOT_NAVIGATING.holds, field="nav_status"),
        )  # fmt: skip

    async def goto(
        self,
        target_id: int,
        *,
        timeout: float | RobotDefault | None = ROBOT_DEFAULT,
        accept_timeout: float | None = None,
        progress_timeout: float | RobotDefault | None = ROBOT_DEFAULT,
        cancel_on_exit: bool = True,
    ) -> GoalResult:
        """Go to map target ``target_id``; return a GoalResult on arrival, else raise.

        GoalRejected, GoalAborted (stopped short), GoalCancelled (cancelled or preempted),
        AcceptTimeout, OperationTimeout (after ``timeout`` s: left out, the Robot's
        ``goal_timeout``, 600 s unless set; None: no limit), GoalStalled (running and not
        paused, neither the pose moved nor target_distance fell 0.1 m for
        ``progress_timeout`` s: left out, the Robot's ``progress_timeout``, 60 s unless set;
        None: never), ConnectionLost or LinkStale (on a lost or stale link before the send:
        nothing is sent). A stale link mid-goal is no end (its silence stops the accept and
        progress clocks); a lost one raises ConnectionLost. Cancelled, timed out or stalled,
        it sends ``i 2`` first (a stall: GoalStalledEvent too); ``cancel_on_exit`` False
        leaves a goal the robot showed accepted running, and still cancels one written and
        not yet accepted, so that it cannot start later unseen; a goal left on a lost or
        stale link that still runs once back is cancelled then (AbandonedGoalCancelled). At
        the target already: GoalResult ``already_there`` True.
        """
        return await self._goto(Goto(target_id), timeout, accept_timeout, progress_timeout,
                                cancel_on_exit)  # fmt: skip

    async def _goto(
        self,
        command: Goto,
        timeout: float | RobotDefault | None,
        accept_timeout: float | None,
        progress_timeout: float | RobotDefault | None,
        cancel_on_exit: bool,
    ) -> GoalResult:
        self._ops.check_not_driving("goto_pose" if isinstance(command, PoseGoal) else "goto")
        seconds = or_default(timeout, self.goal_timeout)
        check_timeout("timeout", seconds)
        check_timeout("accept_timeout", accept_timeout)
        progress = or_default(progress_timeout, self.progress_timeout)
        check_timeout("progress_timeout", progress)
        check_bool("cancel_on_exit", cancel_on_exit)
        accept = self.accept_timeout if accept_timeout is None else accept_timeout
        try:
            return await self._goals.run(
                command, deadline=Deadline(seconds), accept_timeout=accept,
                arrive_tolerance=self.arrive_tolerance, progress_timeout=progress,
                cancel_on_exit=cancel_on_exit,
            )  # fmt: skip
        except CommandSuperseded as exc:  # a user stop came before ``g N`` was written
            raise goal_superseded(exc, command.target_id) from exc

    async def goto_point(
        self,
        x: float,
        y: float,
        *,
        timeout: float | RobotDefault | None = ROBOT_DEFAULT,
        progress_timeout: float | RobotDefault | None = ROBOT_DEFAULT,
        cancel_on_exit: bool = True,
    ) -> GoalResult:
        """Reset the dynamic targets, add one at (x, y) metres in the map frame, go there.

        Raises as goto does, and GoalAborted when the robot ends farther than
        ``arrive_tolerance`` from (x, y) (the target numbering is wrong: ``map_targets``);
        InvalidArgument, nothing sent, when ``map_targets`` contradicts the count the link
        read at connect (sim://, ros://).
        """
        command = AddTarget(x, y)  # validate before anything is sent
        self._ops.check_not_driving("goto_point")
        if self._link.capabilities.pose_goals:  # http://: one nav task, followed as target -2
            result = await self._goto(PoseGoal(x=x, y=y), timeout, None, progress_timeout,
                                      cancel_on_exit)  # fmt: skip
            return landed_at(result, x, y, self.arrive_tolerance)
        seconds = or_default(timeout, self.goal_timeout)
        check_timeout("timeout", seconds)
        progress = or_default(progress_timeout, self.progress_timeout)
        check_timeout("progress_timeout", progress)
        check_bool("cancel_on_exit", cancel_on_exit)
        first_id = self._targets.map_target_count("goto_point")
        deadline = Deadline(seconds)
        stops_at = self._ops.supersession.stops  # a user stop supersedes every step still to come
        try:
            await self._targets.reset(
                deadline, what="goto_point", require=GOAL_READY, stops_at=stops_at
            )
            target_id = await self._targets.add(command, deadline, stops_at=stops_at)
            result = await self._goals.run(
                Goto(target_id), deadline=deadline, accept_timeout=self.accept_timeout,
                arrive_tolerance=self.arrive_tolerance, progress_timeout=progress,
                cancel_on_exit=cancel_on_exit, stops_at=stops_at,
            )  # fmt: skip
        except CommandSuperseded as exc:  # a user stop came before the last step was written
            raise goal_superseded(exc, first_id) from exc
        return landed_at(result, x, y, self.arrive_tolerance)

    async def run_mission(
        self,
        mission: Mission,
        *,
        releases: AbcMapping[str, Callable[[], Awaitable[object]]] | None = None,
        journal: str | Path | None = None,
        resume: bool = False,
        on_progress: Callable[[MissionEvent], None] | None = None,
        http_client: object = None,
        journal_max_age: float | None = None,
    ) -> MissionReport:
        """Run ``mission`` on this robot: galileo_async.missions.run_mission (docs/missions.md).

        ``journal_max_age`` None: the runner's default (a day).
        """
        self._ops.ensure_loop()
        # The missions layer sits above the Robot: loaded on first use, not with the Robot.
        from ..missions.runner import DEFAULT_JOURNAL_MAX_AGE, run_mission

        max_age = DEFAULT_JOURNAL_MAX_AGE if journal_max_age is None else journal_max_age
        return await run_mission(
            self, mission, releases=releases, journal=journal, resume=resume,
            on_progress=on_progress, http_client=http_client, journal_max_age=max_age,
        )  # fmt: skip

    def __repr__(self) -> str:
        return f"<Robot on {self._link!r}, link {self.link_state.value}>"

    # --- goal control, dynamic targets ---------------------------------------------------

    async def pause(self, *, timeout: float | None = DEFAULT_TIMEOUT) -> None:
        """Pause the working goal; return once the status shows it paused (a user stop)."""
        await self._goals.pause(timeout)

    async def resume(self, *, timeout: float | None = DEFAULT_TIMEOUT) -> None:
        """Resume the paused goal; return once the status shows it working."""
        await self._goals.resume(timeout)

    async def cancel(self, *, timeout: float | None = DEFAULT_TIMEOUT) -> None:
        """Cancel the goal (sent at once, even while busy or stale); return once none is active.

        On a stale link ``i 2`` is still sent (the transmit side may work), then LinkStale
        is raised: the status cannot confirm it.
        """
        await self._goals.cancel(timeout)

    async def add_target(
        self, x: float, y: float, *, timeout: float | None = DEFAULT_TIMEOUT
    ) -> int:
        """Append a dynamic target at (x, y) metres in the map frame; return its goal id."""
        command = AddTarget(x, y)
        check_timeout("timeout", timeout)
        return await self._targets.add(command, Deadline(timeout))

    async def reset_targets(self, *, timeout: float | None = DEFAULT_TIMEOUT) -> None:
        """Drop every dynamic target (the map's own stay); not confirmable by status."""
        check_timeout("timeout", timeout)
        await self._targets.reset(Deadline(timeout))

    # --- turning ---------------------------------------------------------------------------

    async def rotate_to(
        self, degrees: float, *, timeout: float | None = ROTATE_TIMEOUT, fallback: bool = False
    ) -> None:
        """Rotate to ``degrees`` (-180..180, rounded) in the map frame; wait angle_goal_status.

        Returns once angle_goal_status shows this rotation done (0, then 1). A navigation
        goal that runs meanwhile (this Robot's or another host's) raises OperationFailed:
        it replaces the rotation, and on real firmware angle_goal_status follows it. Facing
        ``degrees`` already, within ``angle_tolerance`` (-180 and 180 are one heading), it
        returns at once and sends nothing. ``fallback``: when ``a`` is unconfirmed
        (UnconfirmedOperation), turn_to() after it.
        """
        try:
            await rotate(self._ops, degrees, limit=timeout, tolerance=self.angle_tolerance)
        except UnconfirmedOperation:
            if not fallback:
                raise
            await self.turn_to(degrees, timeout=timeout)

    async def turn_to(self, degrees: float, *, timeout: float | None = ROTATE_TIMEOUT) -> None:
        """Turn in place to ``degrees`` by drive() (every firmware), within angle_tolerance."""
        self._ops.ensure_loop()
        await turn_in_place(self, degrees, limit=timeout)

    # --- patrol, mapping, charging, host -------------------------------------------------

    async def start_patrol(
        self, dwell: int | None = None, *, timeout: float | None = DEFAULT_TIMEOUT
    ) -> None:
        """Start auto-patrol (``dwell`` s at each target if given); return once loop_status is 1."""
        await self._patrol.start(dwell, timeout)

    async def stop_patrol(self, *, timeout: float | None = DEFAULT_TIMEOUT) -> None:
        """Stop auto-patrol, keep navigation (``m 6``); return once loop_status is 0."""
        await self._patrol.stop(timeout)

    async def set_patrol_dwell(
        self, seconds: int, *, timeout: float | None = DEFAULT_TIMEOUT
    ) -> None:
        """Set the patrol wait at each target (0-255 s); the firmware also starts patrol."""
        await self._patrol.set_dwell(seconds, timeout)

    async def start_mapping(self, *, timeout: float | None = DEFAULT_TIMEOUT) -> None:
        """Start building a map; return once map_status is 1. Navigation must be closed."""
        await self._mapping.start(timeout)

    async def stop_mapping(self, *, timeout: float | None = DEFAULT_TIMEOUT) -> None:
        """Stop building the map; return once map_status is 0."""
        await self._mapping.stop(timeout)

    async def save_map(self, *, timeout: float | None = DEFAULT_TIMEOUT) -> None:
        """Save the map; the status cannot confirm it and some firmware ignores it."""
        await self._mapping.save(timeout)

    async def update_map(self, *, timeout: float | None = DEFAULT_TIMEOUT) -> None:
        """Update the map; the status cannot confirm it."""
        await self._mapping.update(timeout)

    async def start_charging(self, *, timeout: float | None = DEFAULT_TIMEOUT) -> ChargeStatus:
        """Dock and charge (``j 0``); return the charge_status once it leaves FREE.

        This is the local infrared docking only: it does not cross the map. The robot must
        already be near the dock with navigation open; drive it there first (``goto_point``).
        """
        return await self._charging.start(timeout)

    async def stop_charging(self, *, timeout: float | None = DEFAULT_TIMEOUT) -> None:
        """Stop charging; return once charge_status is FREE."""
        await self._charging.stop(timeout)

    async def save_dock(self, *, timeout: float | None = DEFAULT_TIMEOUT) -> None:
        """Save the current pose as the dock position; the status cannot confirm it."""
        await self._charging.save_dock(timeout)

    async def shutdown_host(self, *, confirm: bool = False) -> None:
        """Power the navigation computer off; refuses unless ``confirm=True``."""
        if confirm is not True:
            raise InvalidArgument(
                "shutdown_host powers the robot's computer off: pass confirm=True"
            )
        await self._ops.send(ShutdownHost(), what="shutdown_host")

    # --- lifecycle -----------------------------------------------------------------------

    async def close(self) -> None:
        """Close the link and end every iterator and waiter; idempotent and bounded.

        A cancelled caller waits for the link to close (seconds at most), then is cancelled.
        """
        self._ops.user_stopped("close()")
        task = self._close_task
        if task is None:
            stop_written = self._ops.supersession.drive.end()  # queued by the user stop above
            self._ops.closed = True
            task = self._close_task = asyncio.get_running_loop().create_task(
                self._shutdown(stop_written), name=f"close {self._link!r}"
            )
        await finish_shielded(task, "close()")

    async def _shutdown(self, stop_written: asyncio.Future[bool] | None) -> None:
        try:
            await asyncio.gather(*(closer() for closer in self._closers), return_exceptions=True)
            held = self._ops.supersession.held
            waits = held | ({stop_written} if stop_written is not None else set())
            if waits:  # the drive's stop, and a stop() under way, are written in full first
                await asyncio.wait(waits, timeout=CANCEL_SEND_TIMEOUT)
            await self._link.close()
            await self._ops.aclose()  # exit cancels the closed link failed: let them end
        finally:
            self._store.close()
            OPEN_ROBOTS.discard(self)  # open until its link is closed

    async def __aenter__(self) -> Robot:
        return self

    async def __aexit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        await self.close()
