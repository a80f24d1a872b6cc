"""SimulatedDevice: the robot's side of a simulated_robot(): what it got, what it does next."""

from __future__ import annotations

import asyncio
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from .._checks import check_seconds, check_timeout
from ..errors import GalileoError, GalileoTimeout
from ..models import GalileoStatus, Pose
from ..protocol import Command
from ..sim import SimState, Simulator

if TYPE_CHECKING:
    from ..sim.http import HttpFace
    from .clock import VirtualClock

__all__ = ["ReceivedCommand", "SimulatedDevice"]


@dataclass(frozen=True)
class ReceivedCommand:
    """One command as the robot received it."""

    #: Simulated seconds since the robot started when it arrived.
    at: float
    #: The protocol's command object (``galileo_async.protocol.commands``).
    command: Command
    #: The robot was busy: the command waited (firmware queue) before it ran.
    busy: bool


class SimulatedDevice:
    """The device side of one simulated robot: the commands it received and a script of faults.

    Every scripting call takes effect at the robot's next frame; none sends anything.
    """

    def __init__(self, simulator: Simulator, clock: VirtualClock | None) -> None:
        self.simulator = simulator
        self._clock = clock
        #: The simulator's HTTP face (simulated_robot(link="http")): its ``spoken`` texts,
        #: its ``current`` map and path, its ``tasks``; None on other links.
        self.http_face: HttpFace | None = None
        self._log: list[ReceivedCommand] = []
        model = simulator.model
        self._model = model

        def record(command: Command) -> None:
            received = ReceivedCommand(model.time, command, model.busy or model.pending > 0)
            self._log.append(received)
            for kinds, waiter in list(self._waiters):
                if not waiter.done() and (not kinds or isinstance(command, kinds)):
                    waiter.set_result(received)

        self._waiters: list[tuple[tuple[type[Command], ...], asyncio.Future[ReceivedCommand]]]
        self._waiters = []

        simulator.on_command(record)

    # ------------------------------------------------------------------ what it saw
    @property
    def commands(self) -> list[ReceivedCommand]:
        """Every command received since the start or the last clear(), in order, with its time."""
        return list(self._log)

    def received(self, *kinds: type[Command]) -> list[Command]:
        """The command objects received, in order; with ``kinds``, only those types."""
        return [r.command for r in self._log if not kinds or isinstance(r.command, kinds)]

    async def next_command(self, *kinds: type[Command], timeout: float = 10.0) -> ReceivedCommand:
        """The next command (of ``kinds``, if given) to arrive from now on.

        GalileoTimeout after ``timeout`` seconds of loop time (virtual with the virtual clock).
        """
        check_seconds("timeout", timeout)
        waiter: asyncio.Future[ReceivedCommand] = asyncio.get_running_loop().create_future()
        entry = (kinds, waiter)
        self._waiters.append(entry)
        try:
            return await asyncio.wait_for(waiter, timeout)
        except asyncio.TimeoutError:
            wanted = ", ".join(kind.__name__ for kind in kinds) or "any command"
            raise GalileoTimeout(
                f"next_command: no {wanted} arrived within {timeout} s", self.status
            ) from None
        finally:
            self._waiters.remove(entry)

    def clear(self) -> None:
        """Forget the commands received so far."""
        self._log.clear()

    @property
    def state(self) -> SimState:
        """The simulator's live view (true pose, targets, counters)."""
        return self.simulator.state

    @property
    def status(self) -> GalileoStatus:
        """The status the robot's next frame carries (all v2 fields)."""
        return self._model.status()

    @property
    def pose(self) -> Pose:
        """The robot's true pose, known even when its status does not show it."""
        return self.simulator.state.pose

    @property
    def time(self) -> float:
        """Simulated seconds since the robot started."""
        return self._model.time

    # ------------------------------------------------------------------ script
    def reject_next_goal(self) -> None:
        """Refuse the next goal the way the firmware refuses an unknown target id.

        Real firmware shows it as target_status -1 with the id unchanged (GoalRejected);
        where -1 shows already (navigation just started, no goal yet) the Robot sees no
        change and raises AcceptTimeout, as on the real robot. Document firmware: 3.
        """
        self._model.reject_next_goal()

    def lock_out_start(self) -> None:
        """Begin the firmware's start lockout now: a start within start_ignore_time is ignored."""
        self._model.lock_out_start()

    def abort_next_goal(self) -> None:
        """Make the planner give up half way to the next goal (it ends free, far away)."""
        self._model.abort_next_goal()

    def go_charge(self) -> None:
        """Head for the dock by itself, as a robot with a low battery does (``j 0`` unsent).

        The running goal ends (free, target -1: the Robot sees a cancel from elsewhere) and
        patrol stops; the robot finds the dock, docks and charges (charge_status 3, 4, 1,
        then 2 once full). A mission waits for the charge to end, then goes on.
        """
        self._model.go_charge()

    def busy(self, seconds: float) -> None:
        """Be busy for ``seconds`` from now (commands wait); 0 ends busy now."""
        self._model.hold_busy(check_seconds("seconds", seconds, allow_zero=True))

    def lose_visual(self, seconds: float | None = None) -> None:
        """Lose visual tracking (visual_status 2; the robot halts, a goal stays working).

        Tracking comes back after ``seconds``, or with ``set(visual_status=1)``.
        """
        self._model.lose_visual(check_timeout("seconds", seconds))

    def freeze(self) -> None:
        """The navigation stack dies: the same status again and again with a live counter."""
        self._model.freeze()

    def thaw(self) -> None:
        """The navigation stack comes back where it froze."""
        self._model.thaw()

    def mute(self) -> None:
        """Send no more frames, the connection left open (the link turns stale); commands work."""
        self.simulator.muted = True

    def unmute(self) -> None:
        """Send frames again (the link is fresh again with the next one)."""
        self.simulator.muted = False

    def drop_link(self) -> None:
        """Cut the connection and refuse new ones until restore_link() (the driver retries)."""
        self.simulator.refuse_connections = True
        self.simulator.drop_connections()

    def restore_link(self) -> None:
        """Take connections again: the driver's next retry reconnects."""
        self.simulator.refuse_connections = False

    def place(self, x: float, y: float, heading: float = 0.0) -> None:
        """Put the robot at (x, y) metres facing ``heading`` radians, at rest."""
        self._model.place(x, y, heading)

    def set(self, **fields: Any) -> None:
        """Override status fields from the next frame on (``power=22.5``, ``charge_status=1``).

        Settable: galileo_async.sim.SETTABLE_FIELDS; InvalidArgument, nothing changed, for
        any other name or a value that is not a finite number.
        """
        self._model.set_fields(**fields)

    # ------------------------------------------------------------------ time
    async def advance(self, seconds: float) -> None:
        """Run ``seconds`` of time at once: the robot and every driver timer, in order."""
        if self._clock is None:
            raise GalileoError("advance() needs simulated_robot(clock='virtual')")
        await self._clock.advance(seconds)
