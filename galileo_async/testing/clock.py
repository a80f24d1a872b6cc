"""VirtualClock: an event loop's time made virtual, jumping ahead whenever the loop is idle."""

from __future__ import annotations

import asyncio
import selectors
import time
import weakref
from collections.abc import Callable, Mapping
from typing import Any

from .._checks import check_seconds
from ..errors import GalileoError

__all__ = ["UnsupportedLoop", "VirtualClock"]

#: Longest real wait of one idle turn while a thread works for the loop.
_THREAD_POLL = 0.05

_CLOCKS: weakref.WeakKeyDictionary[asyncio.AbstractEventLoop, VirtualClock] = (
    weakref.WeakKeyDictionary()
)


def _follow_anyio_threads() -> None:
    """Count anyio's worker threads (to_thread.run_sync, open_file) as work for the loop.

    anyio runs them on threads of its own, not run_in_executor: its asyncio backend's
    entry point is wrapped once, and does what it did wherever no virtual clock runs.
    Another anyio (no such entry point) is left as it is: its threads are not waited for.
    """
    try:
        from anyio._backends._asyncio import AsyncIOBackend
    except ImportError:
        return
    entry = AsyncIOBackend.__dict__.get("run_sync_in_worker_thread")
    if not isinstance(entry, classmethod) or getattr(entry.__func__, "_follows_clock", False):
        return
    original = entry.__func__

    async def run_sync_in_worker_thread(cls: Any, *args: Any, **kwargs: Any) -> Any:
        clock = _CLOCKS.get(asyncio.get_running_loop())
        if clock is None:
            return await original(cls, *args, **kwargs)
        clock._threads += 1
        try:
            return await original(cls, *args, **kwargs)
        finally:
            clock._threads -= 1

    run_sync_in_worker_thread._follows_clock = True  # type: ignore[attr-defined]
    AsyncIOBackend.run_sync_in_worker_thread = classmethod(run_sync_in_worker_thread)  # type: ignore[method-assign, assignment]


class UnsupportedLoop(GalileoError, RuntimeError):
    """The running event loop cannot take a virtual clock (not asyncio's selector loop)."""


class _Shifted:
    """A loop's time going on at the real rate from where a virtual clock left it."""

    __slots__ = ("_base", "_shift")

    def __init__(self, base: Callable[[], float], shift: float) -> None:
        self._base = base
        self._shift = shift

    @classmethod
    def of(cls, base: Callable[[], float], shift: float) -> Callable[[], float]:
        """``base`` shifted by ``shift`` seconds (``base`` itself for no shift)."""
        if isinstance(base, _Shifted):
            shift += base._shift
            base = base._base
        return base if shift == 0 else cls(base, shift)

    def __call__(self) -> float:
        return self._base() + self._shift


class _IdleSelector(selectors.BaseSelector):
    """The loop's selector, asked first without waiting; an idle loop moves the clock instead."""

    def __init__(self, clock: VirtualClock, real: selectors.BaseSelector) -> None:
        self.clock = clock
        self.real = real

    def register(self, fileobj: Any, events: int, data: Any = None) -> selectors.SelectorKey:
        return self.real.register(fileobj, events, data)

    def unregister(self, fileobj: Any) -> selectors.SelectorKey:
        return self.real.unregister(fileobj)

    def modify(self, fileobj: Any, events: int, data: Any = None) -> selectors.SelectorKey:
        return self.real.modify(fileobj, events, data)

    def get_key(self, fileobj: Any) -> selectors.SelectorKey:
        return self.real.get_key(fileobj)

    def get_map(self) -> Mapping[Any, selectors.SelectorKey]:
        return self.real.get_map()

    def close(self) -> None:
        self.real.close()

    def select(self, timeout: float | None = None) -> list[tuple[selectors.SelectorKey, int]]:
        events = self.real.select(0)
        if events or timeout == 0:
            return events
        return self.clock._idle(timeout)


class VirtualClock:
    """Virtual time for one running asyncio selector loop (``loop.time()`` and every timer).

    Time stands still while callbacks run and jumps to the next timer when the loop has
    nothing else to do, so ``await asyncio.sleep(60)`` returns at once with exactly 60 s
    passed, and timeouts fire in a deterministic order. While a thread works for the loop
    (``run_in_executor``, ``to_thread``, ``getaddrinfo``) time follows the real clock.
    Code that waits on real sockets to other processes sees time run ahead: use the real
    clock there. Install with :meth:`install`; :meth:`release` gives the loop back its
    selector and the real clock's pace (its time never goes back).
    """

    def __init__(self, loop: asyncio.AbstractEventLoop) -> None:
        real = getattr(loop, "_selector", None)
        if not isinstance(loop, asyncio.BaseEventLoop) or not isinstance(
            real, selectors.BaseSelector
        ):
            raise UnsupportedLoop(
                f"a virtual clock needs asyncio's selector event loop, not {type(loop).__name__}"
                " (use clock='real')"
            )
        self._loop = loop
        self._real_selector = real
        self._real_time: Callable[[], float] = loop.time
        self._real_executor = loop.run_in_executor
        self._now = loop.time()
        self._threads = 0
        self._settle: list[asyncio.Future[None]] = []
        self._users = 0

    # ------------------------------------------------------------------ life
    @classmethod
    def install(cls, loop: asyncio.AbstractEventLoop | None = None) -> VirtualClock:
        """The running loop's virtual clock, installed now or shared (each install: one release)."""
        loop = loop or asyncio.get_running_loop()
        clock = _CLOCKS.get(loop)
        if clock is None:
            clock = cls(loop)
            _follow_anyio_threads()
            clock._patch()
            _CLOCKS[loop] = clock
        clock._users += 1
        return clock

    @classmethod
    def of(cls, loop: asyncio.AbstractEventLoop | None = None) -> VirtualClock | None:
        """The virtual clock installed on ``loop`` (default: the running one), if any."""
        return _CLOCKS.get(loop or asyncio.get_running_loop())

    @property
    def installed(self) -> bool:
        """True until the last release()."""
        return self._users > 0

    def release(self) -> None:
        """Give back one install(); the last one gives the loop back the real clock's pace.

        The loop's time goes on from the virtual now at the real rate, never back: a
        deadline taken meanwhile (anyio's cancel scopes compare it with the time) stays
        right, and a timer due in 2 virtual seconds is due in 2 real seconds. The loop's
        selector comes back, and its time is its own clock's again, shifted by the lead
        the virtual clock took.
        """
        if self._users == 0:
            return
        self._users -= 1
        if self._users:
            return
        loop: Any = self._loop
        loop._selector = self._real_selector
        loop.__dict__.pop("run_in_executor", None)
        clock = _Shifted.of(self._real_time, self._now - self._real_time())
        loop.__dict__.pop("time", None)
        if clock != loop.time:  # not the loop's own method: keep it
            loop.time = clock
        _CLOCKS.pop(self._loop, None)
        for waiter in self._settle:
            if not waiter.done():
                waiter.set_result(None)
        self._settle.clear()

    def _patch(self) -> None:
        loop: Any = self._loop
        loop.time = self.time
        loop.run_in_executor = self._run_in_executor
        loop._selector = _IdleSelector(self, self._real_selector)

    # ------------------------------------------------------------------ time
    def time(self) -> float:
        """Now, in the loop's time: virtual seconds."""
        return self._now

    async def advance(self, seconds: float) -> None:
        """Let exactly ``seconds`` pass, running every callback and timer due by then in order."""
        delay = check_seconds("seconds", seconds, allow_zero=True)
        if delay:
            await asyncio.sleep(delay)
        await self.settled()

    async def settled(self) -> None:
        """Return once the loop has run everything that is ready, without time passing."""
        if not self.installed:
            return
        waiter = self._loop.create_future()
        self._settle.append(waiter)
        await waiter

    # ------------------------------------------------------------------ the loop's side
    def _idle(self, timeout: float | None) -> list[tuple[selectors.SelectorKey, int]]:
        """The loop has nothing ready: settle waiters, wait for a thread, or jump."""
        if self._settle:
            waiters, self._settle = self._settle, []
            for waiter in waiters:
                if not waiter.done():
                    waiter.set_result(None)
            return []
        if self._threads:
            wait = _THREAD_POLL if timeout is None else min(timeout, _THREAD_POLL)
            began = time.monotonic()
            events = self._real_selector.select(wait)
            self._now += min(time.monotonic() - began, wait)
            return events
        if timeout is None:  # no timer at all: only real I/O or another thread can wake it
            return self._real_selector.select(None)
        scheduled: Any = getattr(self._loop, "_scheduled", ())
        when = self._now + timeout
        if scheduled and scheduled[0]._when <= when + 1e-9:
            when = max(self._now, scheduled[0]._when)  # land exactly on the timer
        self._now = when
        return []

    def _run_in_executor(self, executor: Any, func: Callable[..., Any], *args: Any) -> Any:
        future = self._real_executor(executor, func, *args)
        self._threads += 1

        def done(_: object) -> None:
            self._threads -= 1

        future.add_done_callback(done)
        return future
