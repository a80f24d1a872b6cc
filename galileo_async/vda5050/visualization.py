"""One visualization clock per event loop: every vehicle's visualizations from one timer."""

from __future__ import annotations

import asyncio
import heapq
import itertools
import logging
import weakref
from collections.abc import Callable, Hashable

__all__ = ["KEEP_ALIVE", "TICK", "VisualizationClock", "clock"]

_log = logging.getLogger(__name__)

#: Seconds between two wake-ups of a clock at least: what falls due within one tick goes
#: out together (each vehicle still at its own rate, up to TICK late).
TICK = 0.01
#: Seconds a vehicle whose agvPosition and velocity stay unchanged goes without a
#: visualization at most (VDA 5050 2.0 and 2.1 §6.13: the rate is the integrator's).
KEEP_ALIVE = 1.0


class VisualizationClock:
    """Calls each added callback every ``period`` seconds at its phase, from one loop timer.

    The timer runs only while a callback is added; a callback that raises is logged and
    keeps its turn.
    """

    def __init__(self, loop: asyncio.AbstractEventLoop) -> None:
        self._loop = loop
        self._entries: dict[Hashable, tuple[int, float, Callable[[float], None]]] = {}
        self._due: list[tuple[float, int, Hashable]] = []
        self._tokens = itertools.count()
        self._timer: asyncio.TimerHandle | None = None
        self._last = -TICK

    def __len__(self) -> int:
        return len(self._entries)

    @property
    def running(self) -> bool:
        """True while the loop timer is set."""
        return self._timer is not None

    def add(
        self, key: Hashable, period: float, callback: Callable[[float], None], phase: float
    ) -> None:
        """Call ``callback(now)`` every ``period`` s, first after ``period * phase`` (0–1) s."""
        token = next(self._tokens)
        self._entries[key] = (token, period, callback)
        heapq.heappush(self._due, (self._loop.time() + period * phase, token, key))
        self._schedule()

    def remove(self, key: Hashable) -> None:
        """Stop calling ``key``'s callback (nothing if it was not added)."""
        if self._entries.pop(key, None) is None:
            return
        if not self._entries:
            self._due.clear()
            if self._timer is not None:
                self._timer.cancel()
                self._timer = None

    def _schedule(self) -> None:
        due = self._due
        while due and self._entries.get(due[0][2], (None,))[0] != due[0][1]:
            heapq.heappop(due)  # removed, or added again since
        if not due:
            return
        at = max(due[0][0], self._last + TICK)
        if self._timer is not None:
            if self._timer.when() <= at:
                return
            self._timer.cancel()
        self._timer = self._loop.call_at(at, self._fire)

    def _fire(self) -> None:
        self._timer = None
        now = self._loop.time()
        self._last = now
        due = self._due
        while due and due[0][0] <= now:
            at, token, key = heapq.heappop(due)
            entry = self._entries.get(key)
            if entry is None or entry[0] != token:
                continue
            _, period, callback = entry
            heapq.heappush(due, (max(at + period, now), token, key))
            try:
                callback(now)
            except Exception:
                _log.exception("a visualization failed")
        self._schedule()


_clocks: weakref.WeakKeyDictionary[asyncio.AbstractEventLoop, VisualizationClock] = (
    weakref.WeakKeyDictionary()
)


def clock() -> VisualizationClock:
    """The running event loop's clock (made on first use)."""
    loop = asyncio.get_running_loop()
    found = _clocks.get(loop)
    if found is None:
        found = _clocks[loop] = VisualizationClock(loop)
    return found
