"""Robot: awaitable operations with preconditions, busy back-off and confirmation."""

from __future__ import annotations

import asyncio
from collections.abc import AsyncIterator, Awaitable, Callable
from types import TracebackType

from .._checks import check_bool, check_timeout
from ..errors import (
    CommandSuperseded,
    GalileoTimeout,
    InvalidArgument,
    UnconfirmedOperation,
)
from ..events import Event
from ..models import GalileoStatus
from ..options import DEFAULT_ACCEPT_TIMEOUT, DEFAULT_GOAL_TIMEOUT, DEFAULT_WAIT_TIMEOUT
from ..protocol import (
    AddTarget,
    Command,
    Goto,
    PoseGoal,
    StartNavigation,
    StopNavigation,
    Velocity,
)
from ..state.store import StatusStore, StatusStream
from ..transitions import DEFAULT_ARRIVE_TOLERANCE
from ..transports import Link, LinkStats
from .drive import (
    DEFAULT_DRIVE_RATE,
    DEFAULT_MAX_ANGULAR_SPEED,
    DEFAULT_MAX_LINEAR_SPEED,
    DriveSession,
    SpeedLimits,
)
from .following import Following
from .goal import GoalResult, GoalRunner
from .http_services import HttpServices
from .operations import (
    CANCEL_SEND_TIMEOUT,
    DEFAULT_TIMEOUT,
    GOAL_READY,
    NAVIGATING,
    NOT_NAVIGATING,
    ROTATE_TIMEOUT,
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
from .services import DEFAULT_ANGLE_TOLERANCE, RobotServices
from .supersede import goal_superseded
from .targets import DynamicTargets, landed_at
from .turning import Turning

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


class Robot(Turning, RobotServices, HttpServices, Following):
    """A connected Galileo robot; every method validates, then sends through Operations.send.

    Made of an Operations (checks, sends, follows), a GoalRunner and the DynamicTargets;
    RobotServices holds the methods besides goto and navigation, Following the link state
    and the listeners.
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
        ops = Operations(link, store)
        super().__init__(ops, GoalRunner(ops), DynamicTargets(ops, map_targets))
        self._link, self._store = link, store
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
        """Link statistics: frames, bytes, discards, lost frames, reconnects, layout …"""
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

    async def send(self, command: Command, *, timeout: float | None = DEFAULT_TIMEOUT) -> None:
        """Send any command object as is, after busy back-off; nothing is confirmed."""
        if not isinstance(command, Command):
            raise InvalidArgument(f"expected a protocol command object, got {command!r}")
        if isinstance(command, Velocity) and not self._link.capabilities.velocity:
            raise InvalidArgument("a Velocity goes over ros:// only; use drive() on this link")
        if isinstance(command, PoseGoal) and not self._link.capabilities.pose_goals:
            raise InvalidArgument("a PoseGoal goes over http:// only; use goto_point()")
        await self._written(command, f"send({command!r})", timeout)

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
        return DriveSession(self._ops, self.speed_limits, linear, angular, rate, self._drives)

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
        self._user_stop("stop_navigation()")
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
        it sends ``i 2`` first unless ``cancel_on_exit`` is False (a stall: GoalStalledEvent
        too); a goal left on a lost or stale link that still runs once back is cancelled then
        (AbandonedGoalCancelled). At the target already: GoalResult ``already_there`` True.
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
        self._refuse_while_driving("goto")
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
        self._refuse_while_driving("goto_point")
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
        stops_at = self._ops.stops  # a user stop supersedes every step still to come
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

    def __repr__(self) -> str:
        return f"<Robot on {self._link!r}, link {self.link_state.value}>"

    # --- lifecycle -----------------------------------------------------------------------

    async def close(self) -> None:
        """Close the link and end every iterator and waiter; idempotent and bounded.

        A cancelled caller waits for the link to close (seconds at most), then is cancelled.
        """
        self._ops.user_stopped("close()")
        task = self._close_task
        if task is None:
            stop_written = self._drives.end()  # queued first, and written before closing
            self._ops.closed = True
            task = self._close_task = asyncio.get_running_loop().create_task(
                self._shutdown(stop_written), name=f"close {self._link!r}"
            )
        await finish_shielded(task, "close()")

    async def _shutdown(self, stop_written: asyncio.Future[bool] | None) -> None:
        try:
            await asyncio.gather(*(closer() for closer in self._closers), return_exceptions=True)
            waits = self._ops.held | ({stop_written} if stop_written is not None else set())
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
