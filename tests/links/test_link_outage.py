"""One outage, one report: a peer that goes silent, or a port that reopens with nothing behind it.

The vendor's serial node can die while its port stays openable: every reopen succeeds and
then stays silent. The link reports such an outage once (LinkStale, ConnectionLost), tries
again ever less often, and reports it over (ConnectionRestored) only when frames return.
"""

from __future__ import annotations

import asyncio
import itertools
from typing import Any

from galileo_async import events as ev
from galileo_async.links import open_link
from galileo_async.state import StatusStore
from galileo_async.transports import Link, LinkState
from tests.support.fake_device import FakeDevice

STEP = 2.0
STALE = 0.05
#: The silence after which a connection is given up: stale_reconnect * stale_timeout.
GIVE_UP = 2 * STALE
FAST: dict[str, Any] = {
    "stale_timeout": STALE,
    "stale_reconnect": GIVE_UP / STALE,
    "reconnect_initial": 0.02,
    "reconnect_max": 0.16,
}
#: The waits before each reopen of one outage: doubling from 0.02 s, capped at 0.16 s.
DELAYS = [0.02, 0.04, 0.08, 0.16, 0.16, 0.16]


async def open_silent(device: FakeDevice, links: list[Link]) -> tuple[Link, StatusStore]:
    store = StatusStore()
    link = open_link(device.url, store, **FAST)
    links.append(link)
    await link.open()
    await device.wait_for(lambda: len(device.clients) == 1)
    return link, store


class Seen:
    """Every event a store emits, in order (its listener), and a wait for the next ones."""

    def __init__(self, store: StatusStore) -> None:
        self.events: list[ev.Event] = []
        self._changed = asyncio.Event()
        store.add_event_listener(self._record)

    def _record(self, event: ev.Event) -> None:
        self.events.append(event)
        self._changed.set()

    @property
    def names(self) -> list[str]:
        return [event.name for event in self.events]

    async def wait_count(self, count: int) -> None:
        async def until() -> None:
            while len(self.events) < count:
                self._changed.clear()
                await self._changed.wait()

        await asyncio.wait_for(until(), STEP)


async def test_a_dead_node_is_one_outage_until_frames_return(
    device: FakeDevice, links: list[Link]
) -> None:
    link, store = await open_silent(device, links)
    seen = Seen(store)
    device.push()
    await store.wait_until(lambda s: s.time_stamp == 1, timeout=STEP)
    assert link.state is LinkState.UP
    # The node dies; its port (here: the TCP server) still accepts, and nothing answers.
    await device.wait_for(lambda: device.connections == 1 + len(DELAYS), timeout=5 * STEP)
    assert seen.names == ["LinkStale", "ConnectionLost"]
    assert link.state is LinkState.LOST
    assert link.stats.reconnects >= len(DELAYS) - 1
    assert store.link_error is not None
    # Reopen attempts back off: each silent connection was given GIVE_UP s, then the next
    # waited DELAYS[k] (the first connection's gap also holds the frame before the silence).
    gaps = [b - a for a, b in itertools.pairwise(device.accepted_at)]
    assert len(gaps) == len(DELAYS)
    for gap, delay in zip(gaps[1:], DELAYS[1:], strict=True):
        assert gap >= GIVE_UP + delay * 0.9, (gaps, DELAYS)
    assert gaps[3] - gaps[1] >= (DELAYS[3] - DELAYS[1]) * 0.9, gaps  # they grow
    assert max(gaps[3:]) < GIVE_UP + DELAYS[-1] + 0.5, gaps  # up to the cap
    # The node is back: the first frame, not the reopen, ends the outage, once.
    device.push()
    await seen.wait_count(3)
    assert isinstance(seen.events[2], ev.ConnectionRestored)
    assert link.state is LinkState.UP
    assert store.link_error is None
    device.push()
    await store.wait_until(lambda s: s.time_stamp == 3, timeout=STEP)
    assert seen.names == ["LinkStale", "ConnectionLost", "ConnectionRestored"]


async def test_a_drop_then_silent_reopens_is_one_lost_and_no_stale(
    device: FakeDevice, links: list[Link]
) -> None:
    link, store = await open_silent(device, links)
    seen = Seen(store)
    device.push()
    await store.wait_until(lambda s: s.time_stamp == 1, timeout=STEP)
    await device.drop_clients()  # the node dies, and its port reopens to silence
    await device.wait_for(lambda: device.connections == 4, timeout=5 * STEP)
    assert seen.names == ["ConnectionLost"]
    assert link.state is LinkState.LOST
    device.push()
    await seen.wait_count(2)
    assert seen.names == ["ConnectionLost", "ConnectionRestored"]
    # A new outage starts its back-off over from reconnect_initial.
    dropped = device.connections
    await device.drop_clients()
    await device.wait_for(lambda: device.connections == dropped + 1)
    assert device.accepted_at[-1] - device.accepted_at[-2] < GIVE_UP + DELAYS[-1]
    device.push()
    await seen.wait_count(4)
    assert seen.names == ["ConnectionLost", "ConnectionRestored"] * 2


async def test_a_stale_link_whose_frames_return_is_restored_once(
    device: FakeDevice, links: list[Link]
) -> None:
    store = StatusStore()
    link = open_link(device.url, store, **{**FAST, "stale_reconnect": None})
    links.append(link)
    await link.open()
    await device.wait_for(lambda: len(device.clients) == 1)
    seen = Seen(store)
    device.push()
    await store.wait_until(lambda s: s.time_stamp == 1, timeout=STEP)
    await seen.wait_count(1)
    assert seen.names == ["LinkStale"]
    assert link.state is LinkState.STALE
    device.push()
    await seen.wait_count(2)
    assert seen.names == ["LinkStale", "LinkRestored"]
    assert link.state is LinkState.UP
    assert device.connections == 1
