"""Shared fixtures: every test must leave no task behind."""

from __future__ import annotations

import asyncio
from collections.abc import AsyncIterator

import pytest
from fake_device import FakeDevice
from hypothesis import HealthCheck, settings

from galileo_async.transports import BaseLink

settings.register_profile(
    "ci", max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow]
)
settings.register_profile("dev", max_examples=100, deadline=None)
settings.load_profile("ci")


def _pending_timers(loop: asyncio.AbstractEventLoop) -> set[asyncio.TimerHandle]:
    # The loop keeps its timers in a private heap; only this check reads it.
    scheduled: list[asyncio.TimerHandle] = getattr(loop, "_scheduled", [])
    return {handle for handle in scheduled if not handle.cancelled()}


@pytest.fixture(autouse=True)
async def no_lingering_tasks() -> AsyncIterator[None]:
    """Fail a test that leaves a task running or a timer armed on its event loop."""
    loop = asyncio.get_running_loop()
    before = asyncio.all_tasks()
    timers_before = _pending_timers(loop)
    yield
    for _ in range(3):  # let tasks that are already finishing run to completion
        await asyncio.sleep(0)
    # Setup and teardown may run in different tasks: exclude the one running now.
    current = asyncio.current_task()
    left = [t for t in asyncio.all_tasks() - before - {current} if not t.done()]
    for task in left:
        task.cancel()
    if left:
        await asyncio.gather(*left, return_exceptions=True)
        pytest.fail(f"test left {len(left)} task(s) running: {left}")
    timers = _pending_timers(loop) - timers_before
    if timers:
        described = sorted(map(repr, timers))
        for handle in timers:
            handle.cancel()
        pytest.fail(f"test left {len(timers)} timer(s) armed: {described}")


#: Bound, in seconds, on closing a link a test opened.
LINK_CLOSE_TIMEOUT = 2.0


@pytest.fixture
async def device() -> AsyncIterator[FakeDevice]:
    """A started in-memory fake device (tests/fake_device.py), stopped afterwards."""
    fake = FakeDevice()
    await fake.start()
    yield fake
    await fake.stop()


@pytest.fixture
async def links() -> AsyncIterator[list[BaseLink]]:
    """Links a test opened; all closed at teardown, whatever the test did."""
    opened: list[BaseLink] = []
    yield opened
    for link in opened:
        await asyncio.wait_for(link.close(), LINK_CLOSE_TIMEOUT)
