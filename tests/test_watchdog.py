"""StaleClock: the stale deadlines of a loop's links, coalesced onto one loop timer."""

from __future__ import annotations

import asyncio
import gc
import logging
import math
import time
import weakref
from collections.abc import AsyncIterator

import pytest
from fake_device import MemoryConnector

from galileo_async.link import StreamLink
from galileo_async.link.watchdog import TICKS_PER_TIMEOUT, StaleClock, Ticket, stale_clock
from galileo_async.state import StatusStore

STEP = 2.0  # upper bound for anything that should happen promptly
RESOLUTION = 0.02


class Watched:
    """Records when its checks ran; optionally re-arms itself or fails."""

    def __init__(self, clock: StaleClock, *, rearm: float | None = None, fail: bool = False):
        self.clock = clock
        self.rearm = rearm
        self.fail = fail
        self.ran: list[tuple[Ticket, float]] = []
        self.done = asyncio.Event()

    def _stale_due(self, ticket: Ticket) -> None:
        self.ran.append((ticket, time.monotonic()))
        self.done.set()
        if self.fail:
            raise RuntimeError("broken check")
        if self.rearm is not None:
            self.clock.arm(self, time.monotonic() + self.rearm)
            self.rearm = None


def one_tick_ahead(clock: StaleClock, ticks: int = 2) -> float:
    """The time.monotonic() at which a tick boundary ``ticks`` ticks ahead falls."""
    return (math.ceil(time.monotonic() / clock.resolution) + ticks) * clock.resolution


async def all_ran(watched: list[Watched]) -> None:
    await asyncio.wait_for(asyncio.gather(*(w.done.wait() for w in watched)), STEP)


async def test_deadlines_in_one_tick_run_in_one_timer_call_and_never_early() -> None:
    clock = StaleClock(asyncio.get_running_loop(), RESOLUTION)
    boundary = one_tick_ahead(clock)
    watched = [Watched(clock) for _ in range(50)]
    # Deadlines spread over the tick that ends at the boundary.
    whens = [boundary - RESOLUTION * (0.05 + 0.9 * i / 50) for i in range(50)]
    tickets = {id(clock.arm(w, when)) for w, when in zip(watched, whens, strict=True)}
    assert len(tickets) == 1
    assert clock.armed == 50
    await all_ran(watched)
    assert clock.fired == 1
    for w, when in zip(watched, whens, strict=True):
        assert len(w.ran) == 1
        assert w.ran[0][1] >= when
    assert clock.armed == 0


async def test_deadlines_ticks_apart_run_in_their_own_calls() -> None:
    clock = StaleClock(asyncio.get_running_loop(), RESOLUTION)
    boundary = one_tick_ahead(clock)
    late, early = Watched(clock), Watched(clock)
    clock.arm(late, boundary + 2 * RESOLUTION - RESOLUTION / 2)
    clock.arm(early, boundary - RESOLUTION / 2)  # earlier than the timer armed: re-scheduled
    await all_ran([early])
    assert not late.ran
    await all_ran([late])
    assert clock.fired == 2
    assert early.ran[0][1] < late.ran[0][1]


async def test_a_cancelled_check_never_runs_and_the_last_cancel_stops_the_timer() -> None:
    clock = StaleClock(asyncio.get_running_loop(), RESOLUTION)
    cancelled, kept = Watched(clock), Watched(clock)
    ticket = clock.arm(cancelled, time.monotonic() + RESOLUTION)
    clock.arm(kept, time.monotonic() + 3 * RESOLUTION)
    ticket.cancel(cancelled)
    assert clock.armed == 1
    await all_ran([kept])
    assert not cancelled.ran
    ticket = clock.arm(cancelled, time.monotonic() + 1.0)
    ticket.cancel(cancelled)
    ticket.cancel(cancelled)  # twice: no-op
    assert clock.armed == 0
    # No timer is left armed on the loop: the autouse fixture checks it at teardown.


async def test_a_check_that_rearms_runs_again_in_a_later_call() -> None:
    clock = StaleClock(asyncio.get_running_loop(), RESOLUTION)
    watched = Watched(clock, rearm=RESOLUTION / 4)
    clock.arm(watched, time.monotonic() + RESOLUTION)
    await all_ran([watched])
    watched.done.clear()
    await all_ran([watched])
    assert len(watched.ran) == 2
    first, second = watched.ran
    assert first[0] is not second[0]  # a new bucket, not the one that ran
    assert clock.fired >= 2


async def test_a_failing_check_is_logged_and_the_others_still_run(
    caplog: pytest.LogCaptureFixture,
) -> None:
    clock = StaleClock(asyncio.get_running_loop(), RESOLUTION)
    boundary = one_tick_ahead(clock)
    watched = [Watched(clock, fail=index == 1) for index in range(3)]
    for w in watched:
        clock.arm(w, boundary - RESOLUTION / 2)
    with caplog.at_level(logging.ERROR, logger="galileo_async.link.watchdog"):
        await all_ran(watched)
    assert [len(w.ran) for w in watched] == [1, 1, 1]
    assert "stale check of" in caplog.text
    assert "broken check" in caplog.text
    assert clock.armed == 0


def test_resolution_must_be_positive() -> None:
    loop = asyncio.new_event_loop()
    try:
        for bad in (0.0, -1.0, float("nan")):
            with pytest.raises(ValueError, match="resolution"):
                StaleClock(loop, bad)
    finally:
        loop.close()


async def test_a_loop_shares_one_clock_per_resolution() -> None:
    assert stale_clock(0.5) is stale_clock(0.5)
    assert stale_clock(0.5) is not stale_clock(0.25)


def test_each_loop_gets_its_own_clock_and_a_finished_loop_is_collected() -> None:
    clocks: list[weakref.ref[StaleClock]] = []
    loops: list[weakref.ref[asyncio.AbstractEventLoop]] = []

    async def arm_and_leave() -> None:
        loop = asyncio.get_running_loop()
        clock = stale_clock(1.0)
        assert clock._loop is loop
        clock.arm(Watched(clock), time.monotonic() + 60)  # never runs: the loop ends first
        clocks.append(weakref.ref(clock))
        loops.append(weakref.ref(loop))
        assert len({id(c()) for c in clocks}) == len(clocks)  # one clock per loop

    asyncio.run(arm_and_leave())
    asyncio.run(arm_and_leave())
    gc.collect()
    assert [ref() for ref in clocks] == [None, None]
    assert [ref() for ref in loops] == [None, None]


@pytest.fixture
async def fleet() -> AsyncIterator[list[StreamLink]]:
    links = [
        StreamLink(StatusStore(), MemoryConnector(), stale_timeout=5.0, reconnect=False)
        for _ in range(20)
    ]
    for link in links:
        await link.open()
    yield links
    for link in links:
        await asyncio.wait_for(link.close(), STEP)


def clock_timers(loop: asyncio.AbstractEventLoop) -> list[asyncio.TimerHandle]:
    # The loop keeps its timers in a private heap; only these checks read it.
    scheduled: list[asyncio.TimerHandle] = getattr(loop, "_scheduled", [])
    owners = [getattr(getattr(handle, "_callback", None), "__self__", None) for handle in scheduled]
    return [
        handle
        for handle, owner in zip(scheduled, owners, strict=True)
        if not handle.cancelled() and isinstance(owner, StaleClock)
    ]


async def test_a_fleet_of_links_arms_one_loop_timer(fleet: list[StreamLink]) -> None:
    loop = asyncio.get_running_loop()
    clock = stale_clock(5.0 / TICKS_PER_TIMEOUT)
    assert clock.armed == len(fleet)
    assert len(clock_timers(loop)) == 1
    await fleet[0].close()
    assert clock.armed == len(fleet) - 1
    for link in fleet[1:]:
        await link.close()
    assert clock.armed == 0
    assert clock_timers(loop) == []
