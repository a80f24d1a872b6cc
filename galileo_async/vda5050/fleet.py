"""VehicleFleet: many robots in one process, each its own Vehicle (own MQTT session, last will).

One robot's failure (a link that never opens, a duplicate vehicle, an error) ends that
vehicle only; the others go on. A robot whose link cannot be opened is tried again with
capped back-off; its vehicle joins the broker once the robot is connected.
"""

from __future__ import annotations

import logging
from collections.abc import Awaitable, Callable, Mapping
from dataclasses import dataclass

import anyio

from ..errors import GalileoConnectionError, InvalidArgument
from ..robot import Robot
from .config import VehicleConfig
from .shutdown import ShutdownReport
from .vehicle import Vehicle

__all__ = [
    "DEFAULT_CONNECT_CONCURRENCY",
    "DEFAULT_RETRY_INITIAL",
    "DEFAULT_RETRY_MAX",
    "FleetVehicle",
    "VehicleFleet",
]

_log = logging.getLogger(__name__)

#: Robots whose links are opened at the same time (the others wait their turn).
DEFAULT_CONNECT_CONCURRENCY = 100
#: Seconds before a robot whose link did not open is tried again (doubling each time).
DEFAULT_RETRY_INITIAL = 1.0
#: Longest wait between two tries of a robot whose link never opened.
DEFAULT_RETRY_MAX = 30.0
#: Errors after which a robot's link is tried again; any other (bad options) ends its vehicle.
_RETRIED = (GalileoConnectionError, OSError, TimeoutError)


@dataclass(frozen=True)
class FleetVehicle:
    """One robot of a VehicleFleet: how to open its link, and its vehicle's configuration.

    ``connect``: called for each try, e.g. ``functools.partial(galileo_async.connect, url,
    **options)``; the Robot it returns is closed when its vehicle ends.
    """

    connect: Callable[[], Awaitable[Robot]]
    config: VehicleConfig


class _Member:
    def __init__(self, name: str, spec: FleetVehicle) -> None:
        self.name = name
        self.spec = spec
        self.vehicle: Vehicle | None = None
        #: Why the robot is not (or no longer) a vehicle: the last connect error or the end.
        self.error: BaseException | None = None
        self.ended = False
        self.tried = anyio.Event()


class VehicleFleet:
    """Every robot of ``robots`` ({name: FleetVehicle}) as its own vehicle: ``await run()``.

    run() runs until cancelled; shut_down() shuts every vehicle down at once, as
    Vehicle.shut_down does for one, before run() is cancelled (which sends OFFLINE).
    """

    def __init__(
        self,
        robots: Mapping[str, FleetVehicle],
        *,
        connect_concurrency: int = DEFAULT_CONNECT_CONCURRENCY,
        retry_initial: float = DEFAULT_RETRY_INITIAL,
        retry_max: float = DEFAULT_RETRY_MAX,
    ) -> None:
        if not isinstance(robots, Mapping) or not robots:
            raise InvalidArgument("robots must be a non-empty mapping of name to FleetVehicle")
        identities: dict[tuple[str, str], str] = {}
        for name, spec in robots.items():
            if not isinstance(spec, FleetVehicle):
                raise InvalidArgument(f"robot {name!r}: a FleetVehicle, got {type(spec).__name__}")
            config = spec.config
            key = (config.manufacturer, config.serial_number)
            if key in identities:
                raise InvalidArgument(
                    f"robots {identities[key]!r} and {name!r} are both vehicle "
                    f"{key[0]}/{key[1]}: two vehicles must not share a manufacturer and "
                    "serial number"
                )
            identities[key] = name
        if isinstance(connect_concurrency, bool) or not isinstance(connect_concurrency, int):
            raise InvalidArgument(
                f"connect_concurrency must be an int, got {connect_concurrency!r}"
            )
        if connect_concurrency < 1 or not 0 < retry_initial <= retry_max:
            raise InvalidArgument("connect_concurrency >= 1 and 0 < retry_initial <= retry_max")
        self._members = {name: _Member(name, spec) for name, spec in robots.items()}
        self._limit = anyio.Semaphore(connect_concurrency)
        self._retry = (retry_initial, retry_max)
        self._closing = False

    @property
    def names(self) -> tuple[str, ...]:
        """Every robot's name, in the order given."""
        return tuple(self._members)

    def vehicle(self, name: str) -> Vehicle | None:
        """Robot ``name``'s Vehicle once its robot is connected, else None (KeyError: unknown)."""
        return self._members[name].vehicle

    def error(self, name: str) -> BaseException | None:
        """Why robot ``name`` is not a vehicle now: its last connect error, or what ended it."""
        return self._members[name].error

    def ended(self, name: str) -> bool:
        """True once robot ``name``'s vehicle ended for good (its error says why)."""
        return self._members[name].ended

    async def wait_tried(self, name: str) -> None:
        """Return once robot ``name``'s link was tried once: opened, or failed (error says why)."""
        await self._members[name].tried.wait()

    @property
    def vehicles(self) -> dict[str, Vehicle]:
        """The vehicles of the robots that connected, by robot name (ended ones too: ended())."""
        return {m.name: m.vehicle for m in self._members.values() if m.vehicle is not None}

    async def run(self) -> None:
        """Run every vehicle until cancelled; one's failure is logged and leaves the others."""
        async with anyio.create_task_group() as group:
            for member in self._members.values():
                group.start_soon(self._run_member, member, name=f"vehicle {member.name}")

    async def _connect(self, member: _Member) -> Robot | None:
        """Open ``member``'s robot link, again with back-off; None for a link that cannot be."""
        delay, retry_max = self._retry
        while True:
            try:
                async with self._limit:
                    robot = await member.spec.connect()
                member.tried.set()
                return robot
            except _RETRIED as exc:
                new = str(exc) != str(member.error)
                member.error = exc
                member.tried.set()
                _log.log(logging.WARNING if new else logging.INFO,
                         "robot %s: %s; next try in %.1f s", member.name, exc, delay)  # fmt: skip
            except Exception as exc:  # bad options: every try would fail alike
                member.error, member.ended = exc, True
                member.tried.set()
                _log.error("robot %s: %s: %s", member.name, type(exc).__name__, exc)
                return None
            await anyio.sleep(delay)
            delay = min(delay * 2, retry_max)

    async def _run_member(self, member: _Member) -> None:
        robot = await self._connect(member)
        if robot is None:
            return
        try:
            if self._closing:  # shut_down() came while the link opened
                return
            member.error = None
            member.vehicle = Vehicle(robot, member.spec.config)
            await member.vehicle.run()
        except Exception as exc:  # DuplicateVehicle, a bug: this vehicle only
            member.error, member.ended = exc, True
            _log.error("robot %s: its vehicle ended: %s: %s", member.name, type(exc).__name__, exc)
        finally:
            await robot.close()  # shielded and bounded

    async def shut_down(self, reason: str = "the vehicle shut down") -> dict[str, ShutdownReport]:
        """Vehicle.shut_down(``reason``) on every vehicle at once; the reports by robot name.

        Bounded as one vehicle's is (each runs in its own task); a robot still connecting
        will not become a vehicle.
        """
        self._closing = True
        reports: dict[str, ShutdownReport] = {}

        async def one(name: str, vehicle: Vehicle) -> None:
            reports[name] = await vehicle.shut_down(reason)

        with anyio.CancelScope(shield=True):
            async with anyio.create_task_group() as group:
                for name, vehicle in self.vehicles.items():
                    if not self.ended(name):  # a vehicle that ended has closed its robot
                        group.start_soon(one, name, vehicle)
        return {name: reports[name] for name in self._members if name in reports}
