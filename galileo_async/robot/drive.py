"""DriveSession: velocity control with a keep-alive, ended by one stop whatever way it is left."""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Callable
from dataclasses import dataclass
from types import TracebackType
from typing import TYPE_CHECKING, Any

import anyio

from .._checks import check_number
from ..errors import (
    CommandSuperseded,
    ConnectionLost,
    GalileoConnectionError,
    GalileoError,
    NotReady,
)
from ..options import DEFAULT_MAX_ANGULAR_SPEED, DEFAULT_MAX_LINEAR_SPEED
from ..protocol import Backward, Command, Forward, Stop, TurnLeft, TurnRight, speed_commands
from ..protocol.velocity import Velocity
from .operations import CANCEL_SEND_TIMEOUT
from .supersede import DriveSlot

if TYPE_CHECKING:
    from .operations import Operations

__all__ = [
    "DEFAULT_DRIVE_RATE",
    "DEFAULT_MAX_ANGULAR_SPEED",
    "DEFAULT_MAX_LINEAR_SPEED",
    "MAX_DRIVE_RATE",
    "MIN_DRIVE_RATE",
    "DriveSession",
    "SpeedLimits",
]

_log = logging.getLogger(__name__)

#: Keep-alive rates in Hz: the slowest chassis watchdog stops 1 s after the last command.
MIN_DRIVE_RATE, DEFAULT_DRIVE_RATE, MAX_DRIVE_RATE = 2.0, 5.0, 20.0

# A newer speed command replaces a queued one of the same component; a stop replaces both.
_LINEAR_REPLACED_BY = (Forward, Backward, Stop, Velocity)
_ANGULAR_REPLACED_BY = (TurnLeft, TurnRight, Stop, Velocity)
_Replaced = tuple[type[Command], ...]


@dataclass(frozen=True, slots=True)
class SpeedLimits:
    """The robot's speeds at 100 %: connect()'s max_linear_speed and max_angular_speed."""

    linear: float = DEFAULT_MAX_LINEAR_SPEED
    angular: float = DEFAULT_MAX_ANGULAR_SPEED

    def check(self, linear: float, angular: float) -> tuple[float, float]:
        """(linear, angular) as floats within the limits; else InvalidArgument."""
        return (
            check_number("linear", linear, low=-self.linear, high=self.linear),
            check_number("angular", angular, low=-self.angular, high=self.angular),
        )


class DriveSession:
    """``async with robot.drive(...) as d``: keeps the speed alive at ``rate`` Hz inside.

    Leaving the block by any route writes one stop (shielded, within CANCEL_SEND_TIMEOUT)
    after which nothing of the session is written. A user stop (stop(), cancel(), pause(),
    stop_navigation(), close()) ends the session early, its stop queued at once: nothing
    more is written, set() raises CommandSuperseded, and, when the stop came from another
    task, the block's body is cancelled at once and the block raises CommandSuperseded
    naming the stop.
    """

    def __init__(
        self, ops: Operations, limits: SpeedLimits, linear: float, angular: float, rate: float,
        slot: DriveSlot | None = None,
    ) -> None:  # fmt: skip
        self._linear, self._angular = limits.check(linear, angular)
        self._slot = DriveSlot() if slot is None else slot
        self.rate = check_number("rate", rate, low=MIN_DRIVE_RATE, high=MAX_DRIVE_RATE)
        self._ops = ops
        self._limits = limits
        self._encode(self._linear, self._angular)
        self._stops = ops.supersession.stops
        self._task: asyncio.Task[None] | None = None
        self._due = 0.0
        self._entered = False
        self._ended = False
        self._left = False
        self._stop_written: asyncio.Future[bool] | None = None
        self._end_callbacks: list[Callable[[], None]] = []
        self._scope: anyio.CancelScope | None = None
        self._owner: asyncio.Task[Any] | None = None
        #: The user stop that ended the session ("stop()", "close()" …), if one did.
        self.ended_by: str | None = None
        #: Speed commands this session wrote (queued and not replaced by a newer one).
        self.writes = 0

    @property
    def linear(self) -> float:
        """The linear speed being kept alive, m/s (forward positive)."""
        return self._linear

    @property
    def angular(self) -> float:
        """The angular speed being kept alive, rad/s (counter-clockwise, left, positive)."""
        return self._angular

    @property
    def active(self) -> bool:
        """True inside the block until it is left or a user stop ends it."""
        return self._entered and self._live()

    def set(
        self, *, linear: float | None = None, angular: float | None = None, write: bool = True
    ) -> None:
        """Change the speed (an omitted one is kept); written now, then kept alive.

        ``write=False``: not written now; the next keep-alive (within 1/rate s) carries it,
        so a caller that sets a speed on every status still writes at ``rate`` Hz.

        InvalidArgument for an out-of-range value (nothing changes), CommandSuperseded
        after a user stop ended the session, ConnectionLost while the link is down.
        """
        new = self._limits.check(
            self._linear if linear is None else linear,
            self._angular if angular is None else angular,
        )
        if not self._entered or self._left:
            raise GalileoError("drive: set() is only valid inside the drive block")
        if not self._live():
            by = self.ended_by or (
                "close()" if self._ops.closed else self._ops.supersession.stopped_by
            )
            raise CommandSuperseded(
                f"drive: {by} ended the drive session; nothing was written", superseded_by=by
            )
        self._encode(*new)  # InvalidArgument here changes nothing
        self._linear, self._angular = new
        if write:
            self._write()

    # --- the block ---------------------------------------------------------------------

    async def __aenter__(self) -> DriveSession:
        ops = self._ops
        if self._entered:
            raise GalileoError("drive: a drive session can be entered once")
        ops.ensure_open()
        if self._slot.active:
            raise NotReady("drive: another drive session is active", ops.store.status)
        ops.check_link("drive")
        status = ops.store.status
        if status is not None and status.goal_active:
            raise NotReady(
                f"drive: navigation goal {status.target_num_id} is active; cancel it first",
                status,
            )
        self._entered = True
        self._stops = ops.supersession.stops
        self._write()  # ConnectionLost here: nothing was queued, nothing to stop
        self._task = ops.loop.create_task(self._keep_alive(), name="drive keep-alive")
        self._slot.session = self
        # A user stop from another task ends the block's body at once (end()).
        self._owner = asyncio.current_task()
        self._scope = anyio.CancelScope()
        self._scope.__enter__()
        return self

    async def __aexit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self._left = True
        error = self.end()  # before any await: nothing can be written after the stop
        if self._slot.session is self:
            self._slot.session = None
        ended = self._scope is not None and bool(self._scope.__exit__(exc_type, exc, tb))
        finishing = asyncio.ensure_future(self._finish())
        # Its own task, as Operations.send_cancel_shielded: a second task.cancel() cannot
        # stop the wait for the stop's write either.
        with anyio.CancelScope(shield=True):
            await asyncio.shield(finishing)
        if error is None:
            error = finishing.result()
        if error is not None and (exc_type is None or ended):
            raise ConnectionLost(f"drive: the stop could not be written: {error}") from error
        if ended:
            by = self.ended_by or "a user stop"
            raise CommandSuperseded(f"drive: ended by {by}", superseded_by=by)

    def on_end(self, callback: Callable[[], None]) -> None:
        """Call ``callback`` once when the session ends (a user stop, close() or leaving)."""
        if self._ended:
            callback()
        else:
            self._end_callbacks.append(callback)

    def end(self, by: str | None = None) -> GalileoError | None:
        """End the session and queue its one stop, now; the error if it could not be queued.

        ``by`` names the user stop that ended it ("stop()"). Idempotent: only the first call
        queues a stop. Robot.close() calls it before the link closes.
        """
        if self._ended or not self._entered:
            return None
        self._ended = True
        self.ended_by = by
        callbacks, self._end_callbacks = self._end_callbacks, []
        for callback in callbacks:
            callback()
        if self._scope is not None and asyncio.current_task() is not self._owner:
            self._scope.cancel()  # the body ends now, raising CommandSuperseded
        if self._task is not None:
            self._task.cancel()
        stop: Command = Velocity(0.0, 0.0) if self._ops.link.capabilities.velocity else Stop()
        try:
            self._stop_written = self._ops.link.enqueue(stop)
        except GalileoConnectionError as exc:
            _log.warning("drive: the stop could not be queued: %r", exc)
            return exc
        return None

    @property
    def stop_written(self) -> asyncio.Future[bool] | None:
        """The future of the stop end() queued (None before end() or when it failed)."""
        return self._stop_written

    async def _finish(self) -> GalileoError | None:
        if self._task is not None:
            await asyncio.gather(self._task, return_exceptions=True)
        written = self._stop_written
        if written is None:
            return None
        try:
            await asyncio.wait_for(asyncio.shield(written), CANCEL_SEND_TIMEOUT)
        except (TimeoutError, asyncio.TimeoutError):
            return ConnectionLost(f"not written within {CANCEL_SEND_TIMEOUT} s")
        except GalileoError as exc:
            return exc
        return None

    # --- keep-alive --------------------------------------------------------------------

    def _live(self) -> bool:
        ops = self._ops
        return not (self._ended or ops.closed or ops.supersession.stops != self._stops)

    async def _keep_alive(self) -> None:
        loop = asyncio.get_running_loop()
        while True:
            delay = self._due - loop.time()
            if delay > 0:
                await asyncio.sleep(delay)
                continue
            if not self._live():
                return
            try:
                self._write()
            except GalileoConnectionError as exc:  # down: try again next tick
                _log.debug("drive: keep-alive not written: %r", exc)
                self._due = loop.time() + 1.0 / self.rate

    def _encode(self, linear: float, angular: float) -> list[tuple[Command, _Replaced]]:
        """One write's commands, each with what replaces it queued; InvalidArgument past 100 %."""
        if self._ops.link.capabilities.velocity:
            return [(Velocity(linear, angular), (Stop, Velocity))]
        commands = speed_commands(
            linear, angular, max_linear=self._limits.linear, max_angular=self._limits.angular
        )
        return list(zip(commands, (_LINEAR_REPLACED_BY, _ANGULAR_REPLACED_BY), strict=True))

    def _write(self) -> None:
        """Queue the current speed now, replacing any of this speed still queued."""
        link = self._ops.link
        self._due = self._ops.loop.time() + 1.0 / self.rate
        for command, replaced_by in self._encode(self._linear, self._angular):
            link.enqueue(command, superseded_by=replaced_by).add_done_callback(self._written)

    def _written(self, future: asyncio.Future[bool]) -> None:
        if future.cancelled():
            return
        error = future.exception()
        if error is not None:
            _log.debug("drive: a speed command was not written: %r", error)
        elif future.result():
            self.writes += 1
