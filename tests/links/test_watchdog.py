"""The stale timer: one loop timer per link, moved only when it fires, never reporting early."""

from __future__ import annotations

import asyncio
import math
import time
from fractions import Fraction
from typing import Any

import pytest

from galileo_async import events as ev
from galileo_async.links import open_link
from galileo_async.state import StatusStore
from galileo_async.testing import VirtualClock, simulated_robot
from galileo_async.transports import Link, LinkState, StreamChannel
from tests.support.fake_device import FakeDevice, MemoryConnector, status_frame

STEP = 2.0  # upper bound for anything that should happen promptly
#: The defaults: stale_reconnect (5) x stale_timeout (1 s).
LOST_AFTER = 5.0


def stale_timers(link: Link) -> list[asyncio.TimerHandle]:
    """The armed loop timers whose callback is a method of ``link``."""
    # The loop keeps its timers in a private heap; only these checks read it (as conftest does).
    scheduled: list[asyncio.TimerHandle] = getattr(asyncio.get_running_loop(), "_scheduled", [])
    return [
        handle
        for handle in scheduled
        if not handle.cancelled()
        and getattr(getattr(handle, "_callback", None), "__self__", None) in (link, link.watchdog)
    ]


async def memory_link(links: list[Link], **options: Any) -> tuple[MemoryConnector, Link]:
    connector = MemoryConnector()
    link = Link(StreamChannel(connector), StatusStore(), reconnect=False, **options)
    links.append(link)
    await link.open()
    return connector, link


async def test_stale_is_reported_after_stale_timeout_never_before(
    device: FakeDevice, links: list[Link]
) -> None:
    timeout = 0.2
    store = StatusStore()
    link = open_link(device.url, store, stale_timeout=timeout, reconnect=False)
    links.append(link)
    events = store.events()
    await link.open()
    await device.wait_for(lambda: len(device.clients) == 1)
    device.start_stream(0.01)
    # Frames for several timeouts: the link stays fresh while they flow.
    await store.wait_until(lambda s: (s.time_stamp or 0) >= 3 * timeout / 0.01, timeout=STEP * 5)
    await device.stop_stream()
    last_frame_at = link.stats.last_frame_at
    assert last_frame_at is not None
    stale = await asyncio.wait_for(anext(events), timeout + STEP)
    reported_at = time.monotonic()
    assert isinstance(stale, ev.LinkStaleEvent)  # the first event: never stale while fresh
    assert reported_at - last_frame_at >= timeout
    assert stale.silent_for >= timeout
    assert reported_at - last_frame_at < timeout + STEP
    assert link.stats.stale
    device.push()
    assert isinstance(await asyncio.wait_for(anext(events), STEP), ev.LinkRestored)


async def test_a_frame_only_records_its_time_the_timer_moves_when_it_fires(
    links: list[Link],
) -> None:
    timeout = 1.0
    connector, link = await memory_link(links, stale_timeout=timeout)
    [armed] = stale_timers(link)
    # Frames some way to the deadline armed at connect; a loaded machine has 0.7 s of slack.
    await asyncio.sleep(timeout * 0.3)
    for stamp in range(1, 51):
        connector.feed(status_frame(stamp))
    assert stale_timers(link) == [armed]  # fifty frames moved nothing
    last_frame_at = link.stats.last_frame_at
    assert last_frame_at is not None
    # When it fires, it finds a frame since and re-arms at that frame + stale_timeout.
    loop = asyncio.get_running_loop()
    await asyncio.sleep(armed.when() - loop.time() + 0.001)  # timers run in order of when
    [rearmed] = stale_timers(link)
    assert rearmed is not armed
    due = loop.time() + (last_frame_at + timeout - time.monotonic())  # on the loop's clock
    assert rearmed.when() == pytest.approx(due, abs=1e-3)
    assert not link.stats.stale


async def test_each_link_arms_one_timer_and_close_leaves_none(links: list[Link]) -> None:
    fleet = [(await memory_link(links, stale_timeout=5.0))[1] for _ in range(20)]
    for link in fleet:
        assert len(stale_timers(link)) == 1
    await fleet[0].close()
    assert stale_timers(fleet[0]) == []
    for link in fleet[1:]:
        assert len(stale_timers(link)) == 1
        await link.close()
        assert stale_timers(link) == []


async def test_a_lost_connection_or_no_stale_timeout_leaves_no_timer(
    links: list[Link],
) -> None:
    connector, link = await memory_link(links, stale_timeout=5.0)
    events = link.store.events()
    connector.transport.lose(None)
    assert isinstance(await asyncio.wait_for(anext(events), STEP), ev.ConnectionLostEvent)
    assert stale_timers(link) == []
    _, unwatched = await memory_link(links, stale_timeout=None)
    assert stale_timers(unwatched) == []


async def test_a_stale_link_gives_the_connection_up_after_stale_reconnect(
    device: FakeDevice, links: list[Link]
) -> None:
    timeout = 0.05
    store = StatusStore()
    link = open_link(device.url, store, stale_timeout=timeout, stale_reconnect=2.0, reconnect=False)
    links.append(link)
    events = store.events()
    await link.open()
    await device.wait_for(lambda: len(device.clients) == 1)
    opened_at = time.monotonic()
    assert isinstance(await asyncio.wait_for(anext(events), STEP), ev.LinkStaleEvent)
    lost = await asyncio.wait_for(anext(events), STEP)
    assert isinstance(lost, ev.ConnectionLostEvent)
    assert "giving the connection up" in lost.reason
    assert time.monotonic() - opened_at >= 2.0 * timeout
    assert stale_timers(link) == []


# --- a virtual clock lands exactly on the deadline: no spin at a power of two ----------------


@pytest.mark.timeout(30)  # the spin this guards against freezes virtual time: only this ends it
@pytest.mark.parametrize(
    ("state", "silence"), [(LinkState.STALE, 1.0), (LinkState.LOST, 5.0)], ids=["stale", "lost"]
)
async def test_a_deadline_across_a_power_of_two_of_loop_time_still_fires(
    state: LinkState, silence: float
) -> None:
    # The last frame at t, the timer armed at t + silence: where that sum crosses a power of
    # two it rounds (to even), down a quarter of the time, and the check at that instant
    # measures a silence a hair short of the limit. It must not re-arm the timer for the
    # same instant for ever: on a virtual clock, time would stand still.
    clock = VirtualClock.install()
    try:
        loop = asyncio.get_running_loop()
        for _boundary in range(4):  # a window without such a frame time: try the next one
            boundary = 2.0 ** math.ceil(math.log2(loop.time() + 2 * LOST_AFTER))
            await clock.advance(boundary - silence - 1.0 - loop.time())
            async with simulated_robot() as (robot, device):
                while loop.time() < boundary:
                    last = robot.link.last_frame_at or 0.0
                    exact = Fraction(last) + Fraction(silence)
                    if last + silence >= boundary and Fraction(last + silence) < exact:
                        device.mute()
                        assert await robot.wait_link(state, timeout=2 * LOST_AFTER) is state
                        return
                    await device.advance(1 / 30)
        pytest.fail("no frame time whose deadline rounds down near four powers of two")
    finally:
        clock.release()
