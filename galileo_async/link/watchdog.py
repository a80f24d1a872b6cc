"""StaleClock: every link's stale deadline on an event loop, served by one loop timer.

A link's watchdog fires once per ``stale_timeout`` while frames flow, only to find them
still flowing and re-arm. With a loop timer per link, a fleet of 1000 robots pushes and
pops 1000 timers a second through the loop's heap, whose ordering is Python code, and
makes every other timer of the application slower for it (BENCHMARKS.md §4). A
StaleClock puts the deadlines that fall in one tick (a sixteenth of the timeout) into one
bucket and keeps one loop timer, for the earliest bucket: a check runs at its deadline or
up to one tick after, never before.
"""

from __future__ import annotations

import asyncio
import heapq
import logging
import math
import threading
import time
import weakref
from typing import Protocol

__all__ = ["TICKS_PER_TIMEOUT", "StaleClock", "Ticket", "stale_clock"]

_log = logging.getLogger(__name__)
_monotonic = time.monotonic

#: A deadline is checked at most ``stale_timeout / TICKS_PER_TIMEOUT`` after it falls due.
TICKS_PER_TIMEOUT = 16


class Ticket(list["_Watched"]):
    """The links due in one tick of a clock; a link armed there holds it until it runs."""

    __slots__ = ("clock",)

    def __init__(self, clock: StaleClock) -> None:
        super().__init__()
        self.clock = clock

    def cancel(self, link: _Watched) -> None:
        """Disarm ``link``'s check (no-op once it ran); the clock's last one stops its timer."""
        self.clock._disarm(link, self)


class _Watched(Protocol):
    def _stale_due(self, ticket: Ticket) -> None:
        """The deadline armed with ``ticket`` has come (ignored if no longer armed with it)."""


class StaleClock:
    """One loop's deadlines of one resolution; each bucket of a tick is one timer run."""

    __slots__ = ("__weakref__", "_armed", "_buckets", "_loop", "_ticks", "_timer", "_timer_tick",
                 "fired", "resolution")  # fmt: skip

    def __init__(self, loop: asyncio.AbstractEventLoop, resolution: float) -> None:
        """Deadlines on ``loop``, checked at most ``resolution`` s late."""
        if not resolution > 0:
            raise ValueError(f"resolution must be positive, got {resolution}")
        self.resolution = resolution
        #: Loop timer runs so far (each checks every bucket that has fallen due).
        self.fired = 0
        self._loop = loop
        self._armed = 0  # links in the buckets: the last one disarmed stops the timer
        self._buckets: dict[int, Ticket] = {}
        self._ticks: list[int] = []  # heap of the buckets' ticks
        self._timer: asyncio.TimerHandle | None = None
        self._timer_tick: int | None = None

    @property
    def armed(self) -> int:
        """Links whose check waits for its tick."""
        return self._armed

    def arm(self, link: _Watched, when: float) -> Ticket:
        """Call ``link._stale_due(ticket)`` at ``when`` (time.monotonic) or up to a tick later."""
        tick = math.ceil(when / self.resolution)
        ticket = self._buckets.get(tick)
        if ticket is None:
            ticket = self._buckets[tick] = Ticket(self)
            heapq.heappush(self._ticks, tick)
            if self._timer_tick is None or tick < self._timer_tick:
                self._schedule(tick)
        ticket.append(link)
        self._armed += 1
        return ticket

    def _disarm(self, link: _Watched, ticket: Ticket) -> None:
        try:
            ticket.remove(link)
        except ValueError:
            return  # ran already
        self._armed -= 1
        if not self._armed:
            self._stop()

    def _stop(self) -> None:
        """Nothing is armed: no timer, no buckets (the timer would only find them empty)."""
        if self._timer is not None:
            self._timer.cancel()
        self._timer = self._timer_tick = None
        self._buckets.clear()
        self._ticks.clear()

    def _schedule(self, tick: int) -> None:
        if self._timer is not None:
            self._timer.cancel()
        delay = max(0.0, tick * self.resolution - _monotonic())
        self._timer = self._loop.call_later(delay, self._fire)
        self._timer_tick = tick

    def _fire(self) -> None:
        self._timer = None  # this run's: nothing to cancel
        self.fired += 1
        ticks, buckets = self._ticks, self._buckets
        due = math.floor(_monotonic() / self.resolution)
        due_links: list[tuple[Ticket, list[_Watched]]] = []
        while ticks and ticks[0] <= due:
            ticket = buckets.pop(heapq.heappop(ticks))
            self._armed -= len(ticket)
            due_links.append((ticket, ticket[:]))
            ticket.clear()  # run: cancelling it now changes nothing
        # A link the checks re-arm goes into a new bucket, for the next run: none can make
        # this one go on. While _timer_tick is set, arm() schedules nothing.
        try:
            for ticket, links in due_links:
                for link in links:
                    try:
                        link._stale_due(ticket)
                    except Exception:  # one link's failure must not silence the others'
                        _log.exception("stale check of %r failed", link)
        finally:
            self._timer_tick = None
            if self._armed:
                self._schedule(ticks[0])
            else:
                self._stop()


# Shared per (loop, resolution); weakly: a clock lives while its loop timer or a link holds
# it, so a finished loop and its links are collected with it.
_clocks: weakref.WeakValueDictionary[tuple[int, float], StaleClock]
_clocks = weakref.WeakValueDictionary()
_clocks_lock = threading.Lock()


def stale_clock(resolution: float) -> StaleClock:
    """The running loop's StaleClock of ``resolution`` (made on first use)."""
    loop = asyncio.get_running_loop()
    key = (id(loop), resolution)
    with _clocks_lock:
        clock = _clocks.get(key)
        if clock is None or clock._loop is not loop:  # none yet, or a dead loop's id reused
            clock = _clocks[key] = StaleClock(loop, resolution)
    return clock
