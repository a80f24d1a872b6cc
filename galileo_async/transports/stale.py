"""Watchdog: the one loop timer per link that tells a silent link (stale, then given up)."""

from __future__ import annotations

import asyncio
from collections.abc import Callable

from .stats import LinkStats

__all__ = ["Watchdog"]


class Watchdog:
    """Checks a link for silence on one loop timer; the link decides what silence means."""

    __slots__ = (
        "_fresh", "_give_up", "_stale", "_stats", "_timer", "_watching", "connected_at",
        "stale_reconnect", "stale_timeout",
    )  # fmt: skip

    def __init__(
        self,
        stats: LinkStats,
        stale_timeout: float | None,
        stale_reconnect: float | None,
        *,
        watching: Callable[[], bool],
        fresh: Callable[[], bool],
        stale: Callable[[float], None],
        give_up: Callable[[float], None],
    ) -> None:
        """``watching()``: the link is open and not closing; ``fresh()``: it is UP or
        CONNECTING; ``stale(silent)`` turns it STALE; ``give_up(silent)`` drops it."""
        self.stale_timeout = stale_timeout
        self.stale_reconnect = stale_reconnect
        #: When the current connection opened (the link's clock).
        self.connected_at = 0.0
        self._stats = stats
        self._watching = watching
        self._fresh = fresh
        self._stale = stale
        self._give_up = give_up
        self._timer: asyncio.TimerHandle | None = None

    @property
    def armed(self) -> bool:
        """True while a check is scheduled."""
        return self._timer is not None

    def start(self, connected_at: float) -> None:
        """A connection opened at ``connected_at``: watch it from then."""
        self.connected_at = connected_at
        self.arm_from(connected_at)

    def arm_from(self, alive_at: float) -> None:
        """Check again ``stale_timeout`` after ``alive_at`` (no-op when the timeout is off)."""
        timeout = self.stale_timeout
        self.arm(None if timeout is None else alive_at + timeout)

    def arm(self, deadline: float | None) -> None:
        """Check for silence at ``deadline`` (the link's clock: loop time) on one loop timer.

        Statuses only set last_frame_at; the check re-arms itself from it when it runs, so
        a link moves its timer once per stale_timeout, not per frame.
        """
        self.cancel()
        if deadline is None or self.stale_timeout is None or not self._watching():
            return
        self._timer = asyncio.get_running_loop().call_at(deadline, self._check)

    def cancel(self) -> None:
        """Drop the scheduled check, if any."""
        timer = self._timer
        if timer is not None:
            self._timer = None
            timer.cancel()

    def _check(self) -> None:
        self._timer = None
        timeout = self.stale_timeout
        if timeout is None or not self._watching():
            return
        last = self._stats.last_frame_at
        alive_since = self.connected_at if last is None else max(last, self.connected_at)
        now = self._stats.clock()
        silent = now - alive_since
        # Each check compares now with the deadline the timer is armed at, not the silence
        # with the limit: near a power of two in loop time the sum rounds, and a timer that
        # lands exactly on it (a virtual clock) would be re-armed for the same instant.
        # A lost link reopened is not stale again: its outage is reported already.
        if self._fresh():
            if now < alive_since + timeout:  # a frame came since (or the timer ran early)
                self.arm(alive_since + timeout)
                return
            self._stale(silent)
        # A peer that froze or vanished may keep its TCP connection open: give it up.
        if self.stale_reconnect is None:
            return
        give_up_at = alive_since + self.stale_reconnect * timeout
        if now < give_up_at:
            self.arm(give_up_at)  # a fresh frame re-arms it (last_frame_at)
            return
        self._give_up(silent)
