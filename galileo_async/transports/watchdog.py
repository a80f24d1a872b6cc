"""StaleWatchdog: the one loop timer per link that tells a silent link (stale, then given up)."""

from __future__ import annotations

import asyncio
import logging

from ..errors import GalileoConnectionError, LinkStale
from .stats import LinkState, LinkStats, StatusSink

__all__ = ["StaleWatchdog"]

_log = logging.getLogger("galileo_async.transports.base")


class StaleWatchdog:
    """The stale-link half of BaseLink (a mixin: the state is BaseLink's)."""

    # Its own slots (the only mixin of BaseLink that has some: one layout per class).
    __slots__ = ("_error", "_state", "_watchdog")

    _error: GalileoConnectionError | None
    _state: LinkState
    _watchdog: asyncio.TimerHandle | None

    _closing: bool
    _connected_at: float
    stale_timeout: float | None
    stale_reconnect: float | None
    stats: LinkStats
    store: StatusSink

    def _abandon(self, reason: str) -> None:
        """Give up a silent connection now (BaseLink's)."""
        raise NotImplementedError

    def _set_state(self, state: LinkState) -> None:
        """Change the link's state (BaseLink's)."""
        raise NotImplementedError

    def _stale_message(self, silent: float) -> str:
        """What LinkStale says after ``silent`` seconds without a valid frame."""
        return f"no valid status frame for {silent:.2f} s"

    def _on_stale(self) -> None:
        """The link just turned stale (after the store was told); default: nothing."""

    def _stale_deadline(self, alive_at: float) -> float | None:
        """When a link last heard from at ``alive_at`` turns stale (None: never)."""
        timeout = self.stale_timeout
        return None if timeout is None else alive_at + timeout

    def _arm_watchdog(self, deadline: float | None) -> None:
        """Check for silence at ``deadline`` (the link's clock: loop time) on one loop timer.

        Frames only set last_frame_at; the check re-arms itself from it when it runs, so a
        link moves its timer once per stale_timeout, not per frame.
        """
        self._cancel_watchdog()
        if deadline is None or self.stale_timeout is None or self._closing:
            return
        self._watchdog = asyncio.get_running_loop().call_at(deadline, self._check_stale)

    def _cancel_watchdog(self) -> None:
        timer = self._watchdog
        if timer is not None:
            self._watchdog = None
            timer.cancel()

    def _check_stale(self) -> None:
        self._watchdog = None
        timeout = self.stale_timeout
        if timeout is None or self._closing or not self.stats.connected:
            return
        last = self.stats.last_frame_at
        alive_since = self._connected_at if last is None else max(last, self._connected_at)
        now = self.stats.clock()
        silent = now - alive_since
        # Each check compares now with the deadline the timer is armed at, not the silence
        # with the limit: near a power of two in loop time the sum rounds, and a timer that
        # lands exactly on it (a virtual clock) would be re-armed for the same instant.
        # A lost link reopened is not stale again: its outage is reported already.
        if self._state is LinkState.UP or self._state is LinkState.CONNECTING:
            if now < alive_since + timeout:  # a frame came since (or the timer ran early)
                self._arm_watchdog(alive_since + timeout)
                return
            self._set_state(LinkState.STALE)
            error = self._error = LinkStale(self._stale_message(silent), silent_for=silent)
            _log.warning("%s", error)
            self.store.link_changed(LinkState.STALE, error)
            self._on_stale()
        # A peer that froze or vanished may keep its TCP connection open: give it up.
        if self.stale_reconnect is None:
            return
        give_up_at = alive_since + self.stale_reconnect * timeout
        if now < give_up_at:
            self._arm_watchdog(give_up_at)  # a fresh frame re-arms it (last_frame_at)
            return
        reason = f"no valid status frame for {silent:.2f} s: giving the connection up"
        _log.warning("%s", reason)
        self._abandon(reason)
