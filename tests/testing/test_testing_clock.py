"""VirtualClock (galileo_async.testing): still during callbacks, jumps when idle, exact timers."""

from __future__ import annotations

import asyncio
import math
import threading
import time
from collections.abc import AsyncIterator

import anyio
import pytest

from galileo_async.errors import InvalidArgument
from galileo_async.testing import UnsupportedLoop, VirtualClock

#: Tolerance of float arithmetic on loop times (a deadline is ``now + delay``).
EXACT = 1e-9


def spin(seconds: float) -> None:
    """Keep the CPU busy for ``seconds`` of real time (never yields to the loop)."""
    end = time.perf_counter() + seconds
    while time.perf_counter() < end:
        pass


def follows_real_time(loop: asyncio.AbstractEventLoop) -> bool:
    """The loop's time moves with the real clock while code runs (no virtual clock on it)."""
    real_start = time.monotonic()
    loop_start = loop.time()
    spin(0.01)
    loop_elapsed = loop.time() - loop_start
    return 0.009 <= loop_elapsed <= time.monotonic() - real_start


@pytest.fixture
async def clock() -> AsyncIterator[VirtualClock]:
    """A VirtualClock on the running loop, released after the test."""
    installed = VirtualClock.install(asyncio.get_running_loop())
    try:
        yield installed
    finally:
        installed.release()


async def test_time_stands_still_while_code_runs(clock: VirtualClock) -> None:
    loop = asyncio.get_running_loop()
    seen: list[tuple[float, float]] = []

    def callback() -> None:
        before = loop.time()
        spin(0.02)
        seen.append((before, loop.time()))

    before = loop.time()
    spin(0.02)
    assert loop.time() == before == clock.time()
    loop.call_soon(callback)
    await clock.settled()
    assert len(seen) == 1
    assert seen[0][0] == seen[0][1] == before


async def test_a_long_sleep_returns_at_once_with_exactly_its_time_passed(
    clock: VirtualClock,
) -> None:
    loop = asyncio.get_running_loop()
    start, real_start = loop.time(), time.perf_counter()
    await asyncio.sleep(3600)
    assert loop.time() - start == pytest.approx(3600, abs=EXACT)
    assert time.perf_counter() - real_start < 1.0


async def test_timers_run_in_order_each_at_its_own_time(clock: VirtualClock) -> None:
    loop = asyncio.get_running_loop()
    start = loop.time()
    fired: list[tuple[str, float]] = []
    done = asyncio.Event()

    def fire(name: str) -> None:
        fired.append((name, loop.time() - start))
        if len(fired) == 5:
            done.set()

    loop.call_later(3.0, fire, "c")
    loop.call_later(1.0, fire, "a1")
    loop.call_at(start + 2.0, fire, "b")
    loop.call_later(1.0, fire, "a2")  # same time as a1: scheduled later, runs later
    loop.call_later(0.25, fire, "first")
    await done.wait()
    assert [name for name, _ in fired] == ["first", "a1", "a2", "b", "c"]
    assert [at for _, at in fired] == pytest.approx([0.25, 1.0, 1.0, 2.0, 3.0], abs=EXACT)


async def test_asyncio_timeout_fires_at_the_exact_virtual_time(clock: VirtualClock) -> None:
    loop = asyncio.get_running_loop()
    start = loop.time()
    with pytest.raises(TimeoutError):
        async with asyncio.timeout(10):
            await asyncio.Event().wait()
    assert loop.time() - start == pytest.approx(10, abs=EXACT)


async def test_anyio_fail_after_fires_at_the_exact_virtual_time(clock: VirtualClock) -> None:
    loop = asyncio.get_running_loop()
    start = loop.time()
    with pytest.raises(TimeoutError), anyio.fail_after(7.5):
        await anyio.sleep_forever()
    assert loop.time() - start == pytest.approx(7.5, abs=EXACT)
    assert anyio.current_time() == loop.time()


async def test_time_follows_real_time_while_a_thread_works(clock: VirtualClock) -> None:
    loop = asyncio.get_running_loop()
    start, real_start = loop.time(), time.perf_counter()
    # Idle meanwhile, the loop would jump straight to the 10 s timeout without the thread.
    async with asyncio.timeout(10):
        await asyncio.to_thread(time.sleep, 0.05)
    elapsed, real_elapsed = loop.time() - start, time.perf_counter() - real_start
    assert 0.01 < elapsed <= real_elapsed + 0.01
    # With the thread done, the loop jumps again.
    start = loop.time()
    await asyncio.sleep(100)
    assert loop.time() - start == pytest.approx(100, abs=EXACT)


async def test_anyio_worker_threads_make_time_follow_real_time(clock: VirtualClock) -> None:
    loop = asyncio.get_running_loop()
    start, real_start = loop.time(), time.perf_counter()
    # anyio's own worker threads, not run_in_executor: idle, the loop would jump to 1 s.
    with anyio.fail_after(1):
        await anyio.to_thread.run_sync(time.sleep, 0.05)
    elapsed, real_elapsed = loop.time() - start, time.perf_counter() - real_start
    assert 0.01 < elapsed <= real_elapsed + 0.01
    start = loop.time()
    await asyncio.sleep(100)  # the thread done: jumps again
    assert loop.time() - start == pytest.approx(100, abs=EXACT)


async def test_anyio_worker_threads_without_a_clock_work_as_before() -> None:
    assert VirtualClock.of() is None
    assert await anyio.to_thread.run_sync(sum, [1, 2, 3]) == 6


async def test_run_in_executor_also_makes_time_follow_real_time(clock: VirtualClock) -> None:
    loop = asyncio.get_running_loop()
    release = threading.Event()
    start = loop.time()
    work = loop.run_in_executor(None, release.wait, 5.0)
    loop.call_later(0.03, release.set)  # due in 0.03 s: reached by real time passing
    async with asyncio.timeout(10):
        assert await work is True
    assert 0.025 <= loop.time() - start < 1.0


async def test_install_twice_shares_one_clock_until_the_last_release() -> None:
    loop = asyncio.get_running_loop()
    assert VirtualClock.of() is None
    first = VirtualClock.install()
    try:
        second = VirtualClock.install(loop)
        assert second is first
        assert VirtualClock.of(loop) is first
        second.release()
        assert first.installed
        assert VirtualClock.of() is first
        start = loop.time()
        await asyncio.sleep(60)  # still virtual
        assert loop.time() - start == pytest.approx(60, abs=EXACT)
    finally:
        first.release()
    assert not first.installed
    assert VirtualClock.of() is None
    first.release()  # one more release is a no-op
    assert VirtualClock.of() is None


async def test_release_gives_back_the_real_pace_and_selector_never_going_back() -> None:
    loop = asyncio.get_running_loop()
    clock = VirtualClock.install()
    try:
        assert not follows_real_time(loop)
        await asyncio.sleep(1000)
        left_at = loop.time()
    finally:
        clock.release()
    assert VirtualClock.of() is None
    assert loop.time() >= left_at  # time goes on from where the virtual clock left it
    assert follows_real_time(loop)
    assert "run_in_executor" not in vars(loop)
    # The real selector waits again: a sleep takes its real time.
    real_start = time.monotonic()
    loop_start = loop.time()
    await asyncio.sleep(0.02)
    loop_elapsed = loop.time() - loop_start
    assert 0.019 <= loop_elapsed <= time.monotonic() - real_start
    await clock.settled()  # a released clock has nothing to settle: returns at once


async def test_a_deadline_taken_on_the_virtual_clock_holds_after_release() -> None:
    # anyio.fail_after compares its deadline with the time when it exits: were the time to
    # go back to the real clock on release, the timeout would be swallowed.
    loop = asyncio.get_running_loop()
    with pytest.raises(TimeoutError), anyio.fail_after(5):  # noqa: PT012
        clock = VirtualClock.install()
        try:
            await anyio.sleep_forever()
        finally:
            clock.release()
    assert follows_real_time(loop)


async def test_installing_again_goes_on_from_the_time_the_last_clock_left() -> None:
    loop = asyncio.get_running_loop()
    seen = [loop.time()]
    for _ in range(3):
        clock = VirtualClock.install()
        try:
            assert clock.time() >= seen[-1]
            await asyncio.sleep(100)
            seen.append(loop.time())
        finally:
            clock.release()
        seen.append(loop.time())
    assert seen == sorted(seen)
    assert seen[-1] - seen[0] == pytest.approx(300, abs=1.0)
    assert follows_real_time(loop)


async def test_release_keeps_each_armed_timer_at_its_distance_from_now() -> None:
    loop = asyncio.get_running_loop()
    clock = VirtualClock.install()
    try:
        await asyncio.sleep(500)  # virtual time far ahead of the real clock
        fired = asyncio.Event()
        far = loop.call_later(2.0, fired.set)
        near = loop.call_later(0.2, fired.set)
    finally:
        clock.release()
    try:
        assert far.when() - loop.time() == pytest.approx(2.0, abs=0.05)
        real_start = time.perf_counter()
        async with asyncio.timeout(5):
            await fired.wait()  # the near timer: after ~0.2 real s, neither never nor at once
        assert 0.15 <= time.perf_counter() - real_start < 2.0
    finally:
        far.cancel()
        near.cancel()


async def test_settled_runs_what_is_ready_without_time_passing(clock: VirtualClock) -> None:
    loop = asyncio.get_running_loop()
    ran: list[object] = []

    def chain(step: int) -> None:
        ran.append(step)
        if step < 5:
            loop.call_soon(chain, step + 1)

    async def task() -> None:
        for step in range(3):
            ran.append(f"task {step}")
            await asyncio.sleep(0)

    start = loop.time()
    later = loop.call_later(1.0, ran.append, "later")
    loop.call_soon(chain, 0)
    running = asyncio.create_task(task())
    await clock.settled()
    assert running.done()
    assert [step for step in ran if isinstance(step, int)] == [0, 1, 2, 3, 4, 5]
    assert "task 2" in ran
    assert "later" not in ran
    assert loop.time() == start
    await clock.advance(1.0)
    assert ran[-1] == "later"
    assert loop.time() - start == pytest.approx(1.0, abs=EXACT)
    later.cancel()


async def test_advance_runs_exactly_the_timers_due_by_then(clock: VirtualClock) -> None:
    loop = asyncio.get_running_loop()
    start = loop.time()
    fired: list[float] = []
    handles = [loop.call_later(at, lambda: fired.append(loop.time() - start)) for at in (1, 2, 3)]
    await clock.advance(2.0)
    assert fired == pytest.approx([1.0, 2.0], abs=EXACT)
    assert loop.time() - start == pytest.approx(2.0, abs=EXACT)
    await clock.advance(0)  # only what is ready: no time passes
    assert loop.time() - start == pytest.approx(2.0, abs=EXACT)
    handles[2].cancel()


@pytest.mark.parametrize("seconds", [-1.0, -0.001, math.nan, math.inf, True, "1", None])
async def test_advance_rejects_what_is_not_seconds(clock: VirtualClock, seconds: object) -> None:
    loop = asyncio.get_running_loop()
    start = loop.time()
    with pytest.raises(InvalidArgument, match="seconds"):
        await clock.advance(seconds)  # type: ignore[arg-type]
    assert loop.time() == start


class _NotASelectorLoop(asyncio.AbstractEventLoop):
    """An event loop without asyncio's selector (as uvloop's or a proactor)."""


async def test_a_loop_without_a_selector_is_unsupported() -> None:
    for loop in (_NotASelectorLoop(), asyncio.BaseEventLoop()):
        with pytest.raises(UnsupportedLoop, match="clock='real'"):
            VirtualClock.install(loop)
        assert VirtualClock.of(loop) is None
    with pytest.raises(RuntimeError):  # UnsupportedLoop is a RuntimeError too
        VirtualClock(_NotASelectorLoop())
    assert VirtualClock.of() is None
