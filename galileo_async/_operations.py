"""Building blocks of Robot operations: deadlines, preconditions, busy back-off, confirmation."""

from __future__ import annotations

import asyncio
import contextlib
import math
from collections.abc import Callable
from typing import TYPE_CHECKING

import anyio

from .errors import (
    GalileoError,
    GalileoTimeout,
    InvalidArgument,
    NotReady,
    OperationFailed,
    OperationTimeout,
    UnconfirmedOperation,
)
from .models import GalileoStatus
from .protocol import Cancel, Command

if TYPE_CHECKING:
    from .link import BaseLink
    from .state import StatusStore

__all__ = [
    "CANCEL_SEND_TIMEOUT",
    "DEFAULT_TIMEOUT",
    "ROTATE_TIMEOUT",
    "Deadline",
    "Operations",
    "check_timeout",
]

#: Seconds for the status to confirm a simple command (patrol, mapping, pause …).
DEFAULT_TIMEOUT = 10.0
#: Seconds for a rotation to finish.
ROTATE_TIMEOUT = 20.0
#: Longest a shielded cancel (``i 2``) sent on the way out of an operation may take.
CANCEL_SEND_TIMEOUT = 1.0

Predicate = Callable[[GalileoStatus], bool]


def check_timeout(name: str, value: float | None, *, allow_none: bool = True) -> None:
    """Raise InvalidArgument unless ``value`` is a positive finite number (or None if allowed)."""
    if value is None and allow_none:
        return
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InvalidArgument(f"{name} must be a number of seconds, got {value!r}")
    if not math.isfinite(value) or value <= 0:
        raise InvalidArgument(f"{name} must be positive and finite, got {value!r}")


class Deadline:
    """An absolute point in loop time, or none (wait for ever)."""

    __slots__ = ("at", "start", "timeout")

    def __init__(self, timeout: float | None) -> None:
        self.start = asyncio.get_running_loop().time()
        self.timeout = timeout
        self.at = None if timeout is None else self.start + timeout

    def remaining(self) -> float | None:
        """Seconds left (never negative), or None without a deadline."""
        if self.at is None:
            return None
        return max(0.0, self.at - asyncio.get_running_loop().time())

    def elapsed(self) -> float:
        """Seconds since the deadline was set."""
        return asyncio.get_running_loop().time() - self.start


class Operations:
    """Send commands on behalf of a Robot, after checks, and wait for their effect."""

    def __init__(self, link: BaseLink, store: StatusStore) -> None:
        self.link = link
        self.store = store

    def require(self, ok: Predicate, message: str) -> GalileoStatus:
        """Return the latest status if ``ok`` holds for it; else raise NotReady carrying it."""
        status = self.store.status
        if status is None:
            raise NotReady(f"{message}: no status has been received from the robot yet", None)
        if not ok(status):
            raise NotReady(message, status)
        return status

    async def wait_not_busy(self, deadline: Deadline, what: str) -> None:
        """Wait while busy_status is 1 (the robot would only queue the command), within deadline."""
        status = self.store.status
        if status is None or not status.is_busy:
            return
        try:
            await self.store.wait_until(lambda s: not s.is_busy, timeout=deadline.remaining())
        except GalileoTimeout as exc:
            raise OperationTimeout(
                f"{what}: the robot stayed busy (busy_status 1) for {deadline.elapsed():.1f} s",
                exc.status,
            ) from None

    async def send(self, command: Command, deadline: Deadline, what: str) -> None:
        """Wait out busy_status, then send ``command`` once."""
        await self.wait_not_busy(deadline, what)
        await self.link.send(command)

    async def send_confirmed(
        self,
        command: Command,
        done: Predicate,
        *,
        field: str,
        deadline: Deadline,
        what: str,
        failed: Predicate | None = None,
    ) -> GalileoStatus:
        """Send ``command``, then return the first later status where ``done`` holds.

        Raises UnconfirmedOperation when the status layout lacks ``field`` or the deadline
        passes, OperationFailed when ``failed`` holds for a later status.
        """
        await self.wait_not_busy(deadline, what)
        with self.store.watch() as watch:
            await self.link.send(command)
            latest = self.store.status
            if latest is not None and getattr(latest, field) is None:
                raise UnconfirmedOperation(
                    f"{what}: sent, but the {latest.layout} status layout has no {field} "
                    "field, so the driver cannot confirm it",
                    latest,
                )
            while True:
                try:
                    status = await watch.next(deadline.remaining())
                except (TimeoutError, asyncio.TimeoutError):
                    raise UnconfirmedOperation(
                        f"{what}: sent, but {field} did not show it within {deadline.timeout} s",
                        self.store.status,
                    ) from None
                if failed is not None and failed(status):
                    raise OperationFailed(f"{what}: the robot reported a failure", status)
                if done(status):
                    return status

    async def send_cancel_shielded(self) -> None:
        """Send Cancel (``i 2``) even while the calling task is being cancelled; bounded."""
        # A link that is gone cannot carry it: nothing more can be done from here.
        with (
            anyio.CancelScope(shield=True),
            anyio.move_on_after(CANCEL_SEND_TIMEOUT),
            contextlib.suppress(GalileoError),
        ):
            await self.link.send(Cancel())
