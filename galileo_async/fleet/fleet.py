"""Fleets: many robots in one process, one merged coalesced stream, per-robot link state."""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Awaitable, Callable, Iterable, Iterator, Mapping
from dataclasses import dataclass
from types import TracebackType
from typing import TYPE_CHECKING, Any, Generic, TypeVar

import anyio

from .._checks import check_int, check_timeout
from ..errors import GalileoConnectionError, InvalidArgument, NotReady
from ..models import LinkState
from ..robot import DEFAULT_STOP_TIMEOUT, Robot, StopReport, connect
from ..robot.runtime import finish_shielded
from .streams import (
    DEFAULT_FLEET_EVENT_QUEUE,
    FleetEventStream,
    FleetHub,
    FleetStatusStream,
)

if TYPE_CHECKING:
    from ..missions.events import MissionEvent
    from ..missions.model import Mission
    from ..missions.report import MissionReport

__all__ = [
    "DEFAULT_CONNECT_CONCURRENCY",
    "DEFAULT_RETRY_INITIAL",
    "DEFAULT_RETRY_MAX",
    "Fleet",
    "FleetConnection",
    "FleetEventStream",
    "FleetResult",
    "FleetStatusStream",
    "connect_fleet",
]

_log = logging.getLogger(__name__)

#: Robots that connect at the same time (the others wait their turn).
DEFAULT_CONNECT_CONCURRENCY = 100
#: Seconds before a robot whose first connection failed is tried again (doubling each time).
DEFAULT_RETRY_INITIAL = 1.0
#: Longest wait between two tries of a robot that never connected.
DEFAULT_RETRY_MAX = 30.0
#: Errors after which a robot is tried again; anything else (bad options) is a caller's bug.
_RETRIED = (GalileoConnectionError, OSError, TimeoutError)

_T = TypeVar("_T")


@dataclass(frozen=True)
class FleetResult(Generic[_T]):
    """One robot's outcome of Fleet.each(): its value, or the error it raised."""

    name: str
    value: _T | None = None
    error: Exception | None = None

    @property
    def ok(self) -> bool:
        """True when the operation returned (``error`` is None)."""
        return self.error is None


class _Member:
    """One robot of the fleet: its URL, options, Robot once connected, last connect error."""

    def __init__(self, name: str, url: str, options: dict[str, Any]) -> None:
        self.name = name
        self.url = url
        self.options = options
        self.robot: Robot | None = None
        self.error: BaseException | None = None
        self.attempts = 0
        self.tried = asyncio.Event()


class Fleet:
    """Connected robots by name; ``fleet[name]`` is a Robot, iteration gives the names."""

    def __init__(self, members: dict[str, _Member]) -> None:
        self._members = members
        self._hub = FleetHub()
        self._tasks: set[asyncio.Task[None]] = set()
        self._closed = False
        self._close_task: asyncio.Task[None] | None = None
        self._connect_listeners: list[Callable[[str, Robot], None]] = []

    # --- the mapping -------------------------------------------------------------------

    def __getitem__(self, name: str) -> Robot:
        """The connected Robot ``name``; KeyError if unknown, NotReady if not connected yet."""
        member = self._members[name]
        if member.robot is None:
            why = f": {member.error}" if member.error is not None else ""
            raise NotReady(f"robot {name!r} is not connected ({self.state(name).value}){why}", None)
        return member.robot

    def __len__(self) -> int:
        return len(self._members)

    def __iter__(self) -> Iterator[str]:
        return iter(self._members)

    def __contains__(self, name: object) -> bool:
        return name in self._members

    @property
    def names(self) -> tuple[str, ...]:
        """Every robot's name, in the order given."""
        return tuple(self._members)

    def get(self, name: str) -> Robot | None:
        """The Robot ``name`` if connected, else None (KeyError if unknown)."""
        return self._members[name].robot

    def name_of(self, robot: Robot) -> str:
        """The name of ``robot`` in this fleet (KeyError if it is not one of its robots)."""
        for name, member in self._members.items():
            if member.robot is robot:
                return name
        raise KeyError(robot)

    def url(self, name: str) -> str:
        """The URL robot ``name`` connects to."""
        return self._members[name].url

    def state(self, name: str) -> LinkState:
        """Robot ``name``'s link state now (Robot.link_state); before its first connection
        CONNECTING, and LOST once a try failed (it is tried again with back-off)."""
        member = self._members[name]
        robot = member.robot
        if robot is None:
            return LinkState.CONNECTING if member.attempts == 0 else LinkState.LOST
        return robot.link_state

    def states(self) -> dict[str, LinkState]:
        """Every robot's connection state."""
        return {name: self.state(name) for name in self._members}

    def error(self, name: str) -> BaseException | None:
        """Why robot ``name``'s last connection attempt failed (None once connected)."""
        return self._members[name].error

    @property
    def closed(self) -> bool:
        """True once close() was called."""
        return self._closed

    def add_connect_listener(
        self, listener: Callable[[str, Robot], None], *, connected: bool = False
    ) -> None:
        """Call ``listener(name, robot)`` when a robot connects later (synchronous, cheap).

        ``connected``: also call it now, for each robot connected already (in fleet order),
        so that it hears of every robot once.
        """
        self._connect_listeners.append(listener)
        if connected:
            for name in self.names:
                robot = self.get(name)
                if robot is not None:
                    listener(name, robot)

    def remove_connect_listener(self, listener: Callable[[str, Robot], None]) -> None:
        """Stop calling ``listener`` (no-op if it is not one)."""
        if listener in self._connect_listeners:
            self._connect_listeners.remove(listener)

    # --- streams -----------------------------------------------------------------------

    def statuses(self) -> FleetStatusStream:
        """ONE iterator of ``(name, status)`` over the fleet, coalesced per robot."""
        return self._hub.statuses()

    def events(self, *, maxlen: int = DEFAULT_FLEET_EVENT_QUEUE) -> FleetEventStream:
        """ONE iterator of ``(name, event)`` over the fleet (bounded queue, oldest dropped)."""
        return self._hub.events(maxlen)

    # --- operations --------------------------------------------------------------------

    async def each(
        self,
        operation: Callable[[Robot], Awaitable[_T]],
        names: Iterable[str] | None = None,
    ) -> dict[str, FleetResult[_T]]:
        """Run ``operation(robot)`` on every (or each named) robot at once; results by name.

        An operation's exception becomes its robot's ``error`` (a robot not connected gets
        NotReady without running it); cancelling the call cancels every operation.
        """
        selected = list(self._members) if names is None else list(names)
        unknown = [name for name in selected if name not in self._members]
        if unknown:
            raise InvalidArgument(f"no robot named {', '.join(map(repr, unknown))} in the fleet")
        results: dict[str, FleetResult[_T]] = {}

        async def run(name: str) -> None:
            try:
                value = await operation(self[name])
            except Exception as exc:  # the robot's outcome, not the caller's failure
                results[name] = FleetResult(name, error=exc)
            else:
                results[name] = FleetResult(name, value=value)

        async with anyio.create_task_group() as group:
            for name in dict.fromkeys(selected):
                group.start_soon(run, name)
        return {name: results[name] for name in dict.fromkeys(selected)}

    async def stop(
        self,
        brake: int = 100,
        *,
        timeout: float | None = DEFAULT_STOP_TIMEOUT,  # noqa: ASYNC109 - as Robot.stop's
    ) -> dict[str, FleetResult[StopReport]]:
        """Robot.stop() on every robot at once; its StopReport, or its error, by name.

        A robot that did not confirm within ``timeout`` gets StopUnconfirmed, one not
        connected NotReady (naming why it is not); InvalidArgument at once, nothing sent.
        """
        check_int("brake", brake, 0, 100)
        check_timeout("timeout", timeout)
        return await self.each(lambda robot: robot.stop(brake, timeout=timeout))

    async def run_missions(
        self,
        missions: Mapping[str, Mission],
        *,
        releases: Mapping[str, Callable[[], Awaitable[object]]] | None = None,
        on_progress: Callable[[str, MissionEvent], None] | None = None,
    ) -> dict[str, MissionReport]:
        """Run ``missions[name]`` on robot ``name``, all at once; each MissionReport by name.

        The first user stop (Fleet.stop(), or one robot's mission ending stopped) stops
        every robot, so every mission ends. Every mission is checked first, nothing sent
        (MissionRejected); a robot not connected: NotReady; an unknown name: InvalidArgument.
        ``on_progress(name, event)``: each MissionEvent with its robot's name.
        """
        # The missions layer sits above the fleet: loaded on first use.
        from ..missions.fleet_run import run_missions

        unknown = [name for name in missions if name not in self._members]
        if unknown:
            raise InvalidArgument(f"no robot named {', '.join(map(repr, unknown))} in the fleet")
        robots = {name: self[name] for name in missions}
        return await run_missions(
            robots, missions, stop_all=self.stop, releases=releases, on_progress=on_progress
        )

    # --- lifecycle ---------------------------------------------------------------------

    def _start(self, concurrency: int, retry_initial: float, retry_max: float) -> None:
        """Start connecting every robot (one task each until it is connected)."""
        limit = asyncio.Semaphore(concurrency)
        loop = asyncio.get_running_loop()
        for member in self._members.values():
            task = loop.create_task(
                self._join(member, limit, retry_initial, retry_max), name=f"fleet {member.name}"
            )
            self._tasks.add(task)
            task.add_done_callback(self._tasks.discard)

    async def _join(
        self, member: _Member, limit: asyncio.Semaphore, delay: float, retry_max: float
    ) -> None:
        """Connect ``member``, trying again with capped back-off until it works."""
        while True:
            try:
                async with limit:
                    robot = await connect(member.url, **member.options)
            except _RETRIED as exc:
                member.error = exc
                member.attempts += 1
                member.tried.set()
                _log.info("robot %s: %s; next try in %.1f s", member.name, exc, delay)
                await asyncio.sleep(delay)
                delay = min(delay * 2, retry_max)
                continue
            except Exception as exc:  # bad options: every try would fail alike
                member.error = exc
                member.attempts += 1
                member.tried.set()
                return  # _wait_first_tries raises it
            if self._closed:  # close() came while it connected
                await robot.close()
                return
            member.robot, member.error = robot, None
            member.attempts += 1
            self._hub.attach(member.name, robot)
            for listener in list(self._connect_listeners):
                try:
                    listener(member.name, robot)
                except Exception:  # a broken listener must not keep the robot out
                    _log.exception("connect listener %r failed", listener)
            member.tried.set()
            return

    async def _wait_first_tries(self) -> None:
        """Return once every robot was tried once; raise a caller's error (bad options)."""
        for member in self._members.values():
            await member.tried.wait()
            error = member.error
            if isinstance(error, InvalidArgument):
                raise InvalidArgument(f"robot {member.name!r}: {error}") from error
            if error is not None and not isinstance(error, _RETRIED):
                raise error

    async def close(self) -> None:
        """Stop connecting, close every robot and end the merged streams (idempotent, bounded)."""
        task = self._close_task
        if task is None:
            self._closed = True
            task = self._close_task = asyncio.get_running_loop().create_task(
                self._shutdown(), name="fleet close"
            )
        await finish_shielded(task, "closing the fleet")

    async def _shutdown(self) -> None:
        tasks = list(self._tasks)
        for task in tasks:
            task.cancel()
        if tasks:
            await asyncio.wait(tasks)
        robots = [m.robot for m in self._members.values() if m.robot is not None]
        self._hub.close()
        await asyncio.gather(*(robot.close() for robot in robots), return_exceptions=True)


class FleetConnection:
    """What connect_fleet() returns: ``async with`` it for a Fleet."""

    def __init__(self, fleet: Fleet, concurrency: int, retry: tuple[float, float]) -> None:
        self._fleet = fleet
        self._concurrency = concurrency
        self._retry = retry

    async def __aenter__(self) -> Fleet:
        fleet = self._fleet
        fleet._start(self._concurrency, *self._retry)
        try:
            await fleet._wait_first_tries()
        except BaseException:
            await fleet.close()
            raise
        return fleet

    async def __aexit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        await self._fleet.close()


def _check_positive(name: str, value: object) -> None:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not value > 0:
        raise InvalidArgument(f"{name} must be a positive number, got {value!r}")


def connect_fleet(
    ports: Mapping[str, str],
    *,
    robot_options: Mapping[str, Mapping[str, Any]] | None = None,
    connect_concurrency: int = DEFAULT_CONNECT_CONCURRENCY,
    retry_initial: float = DEFAULT_RETRY_INITIAL,
    retry_max: float = DEFAULT_RETRY_MAX,
    **options: Any,
) -> FleetConnection:
    """Connect every robot of ``ports`` ({name: url}) at once: ``async with connect_fleet(…)``.

    Entering returns once every robot was tried once; a robot that failed is tried again
    in the background (capped back-off from ``retry_initial`` to ``retry_max`` s) and its
    state is LOST meanwhile. ``options`` go to every connect() call, ``robot_options[name]``
    on top of them to that robot's. One robot's failure never blocks the others.
    """
    if not isinstance(ports, Mapping) or not ports:
        raise InvalidArgument(f"ports must be a non-empty mapping of name to URL, got {ports!r}")
    per_robot = dict(robot_options or {})
    members: dict[str, _Member] = {}
    for name, url in ports.items():
        if not isinstance(name, str) or not name:
            raise InvalidArgument(f"robot names must be non-empty strings, got {name!r}")
        if not isinstance(url, str) or not url:
            raise InvalidArgument(f"robot {name!r}: the URL must be a non-empty string: {url!r}")
        extra = per_robot.pop(name, {})
        if not isinstance(extra, Mapping):
            raise InvalidArgument(f"robot {name!r}: options must be a mapping, got {extra!r}")
        members[name] = _Member(name, url, {**options, **extra})
    if per_robot:
        unknown = ", ".join(map(repr, per_robot))
        raise InvalidArgument(f"robot_options name robots not in the fleet: {unknown}")
    if isinstance(connect_concurrency, bool) or not isinstance(connect_concurrency, int):
        raise InvalidArgument(f"connect_concurrency must be an int, got {connect_concurrency!r}")
    _check_positive("connect_concurrency", connect_concurrency)
    _check_positive("retry_initial", retry_initial)
    _check_positive("retry_max", retry_max)
    return FleetConnection(Fleet(members), connect_concurrency, (retry_initial, retry_max))
