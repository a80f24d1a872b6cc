"""The fleet's merged streams, fed by real StatusStores: coalescing, consumers, cancellation."""

from __future__ import annotations

import asyncio
from typing import Any

import anyio
import pytest

import galileo_async.state.store
from galileo_async import events as ev
from galileo_async.errors import ConnectionLost, LinkStale
from galileo_async.events import Event
from galileo_async.fleet.streams import FleetHub, FleetStatusStream
from galileo_async.models import LinkState
from galileo_async.state import StatusStore
from galileo_async.transitions import step_events
from tests.support.cancel_ways import WAYS, stop_waiting
from tests.support.fake_device import make_status

WAIT = 5.0


def fleet_of(*names: str) -> tuple[FleetHub, dict[str, StatusStore]]:
    hub = FleetHub()
    stores = {name: StatusStore() for name in names}
    for name, store in stores.items():
        hub.attach(name, store)
    return hub, stores


async def take(stream: FleetStatusStream, count: int) -> list[tuple[str, int | None]]:
    with anyio.fail_after(WAIT):
        taken = [await anext(stream) for _ in range(count)]
    return [(name, status.time_stamp) for name, status in taken]


async def nothing_pending(stream: FleetStatusStream) -> bool:
    with anyio.move_on_after(0.02):
        await anext(stream)
        return False
    return True


async def test_a_slow_consumer_gets_each_robots_newest_once() -> None:
    hub, stores = fleet_of("a", "b", "c")
    stream = hub.statuses()
    for stamp in range(1, 6):
        stores["a"].update(make_status(time_stamp=stamp))
    stores["b"].update(make_status(time_stamp=100))
    stores["a"].update(make_status(time_stamp=6))
    assert stream.pending() == 2
    assert await take(stream, 2) == [("a", 6), ("b", 100)]
    assert await nothing_pending(stream)
    hub.close()


async def test_an_update_during_a_pass_is_not_handed_out_twice() -> None:
    hub, stores = fleet_of("a", "b")
    stream = hub.statuses()
    stores["a"].update(make_status(time_stamp=1))
    stores["b"].update(make_status(time_stamp=1))
    assert await take(stream, 1) == [("a", 1)]
    stores["b"].update(make_status(time_stamp=2))  # b is in this pass already: its newest
    assert await take(stream, 1) == [("b", 2)]
    assert await nothing_pending(stream)
    stores["b"].update(make_status(time_stamp=3))
    assert await take(stream, 1) == [("b", 3)]
    hub.close()


async def test_a_new_stream_starts_with_every_latest_status() -> None:
    hub, stores = fleet_of("a", "b", "c")
    stores["c"].update(make_status(time_stamp=7))
    stores["a"].update(make_status(time_stamp=8))
    stream = hub.statuses()
    assert sorted(await take(stream, 2)) == [("a", 8), ("c", 7)]
    hub.close()


async def test_any_number_of_independent_consumers() -> None:
    hub, stores = fleet_of("a", "b")
    first, second = hub.statuses(), hub.statuses()
    stores["a"].update(make_status(time_stamp=1))
    assert await take(first, 1) == [("a", 1)]
    stores["b"].update(make_status(time_stamp=2))
    assert await take(second, 2) == [("a", 1), ("b", 2)]
    assert await take(first, 1) == [("b", 2)]
    first.close()
    stores["a"].update(make_status(time_stamp=3))
    assert await take(second, 1) == [("a", 3)]
    with pytest.raises(StopAsyncIteration):
        await anext(first)
    hub.close()


async def test_a_waiting_consumer_is_woken_by_the_next_status() -> None:
    hub, stores = fleet_of("a")
    stream = hub.statuses()
    task = asyncio.create_task(take(stream, 1))
    await asyncio.sleep(0)
    stores["a"].update(make_status(time_stamp=5))
    assert await task == [("a", 5)]
    hub.close()


@pytest.mark.parametrize("how", WAYS)
async def test_cancelled_wait_leaves_the_stream_usable(how: str) -> None:
    hub, stores = fleet_of("a")
    stream = hub.statuses()
    await stop_waiting(how, lambda: anext(stream), 0.02)
    stores["a"].update(make_status(time_stamp=9))
    assert await take(stream, 1) == [("a", 9)]
    hub.close()


async def test_close_ends_a_waiting_consumer() -> None:
    hub, _stores = fleet_of("a")
    stream = hub.statuses()
    task = asyncio.create_task(anext(stream))
    await asyncio.sleep(0)
    hub.close()
    with pytest.raises(StopAsyncIteration), anyio.fail_after(WAIT):
        await task
    assert [item async for item in hub.statuses()] == []


async def test_two_tasks_on_one_stream_is_an_error() -> None:
    hub, _stores = fleet_of("a")
    stream = hub.statuses()
    task = asyncio.create_task(anext(stream))
    await asyncio.sleep(0)
    with pytest.raises(RuntimeError, match="another task"):
        await anext(stream)
    hub.close()
    with pytest.raises(StopAsyncIteration):
        await task


async def test_events_are_named_and_derived_only_while_read(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    derived: list[Event] = []

    def counted(*args: Any) -> list[Event]:
        events = list(step_events(*args))
        derived.extend(events)
        return events

    monkeypatch.setattr(galileo_async.state.store, "step_events", counted)
    hub, stores = fleet_of("a", "b")
    stores["a"].update(make_status(time_stamp=0, nav_status=1))
    stores["a"].update(make_status(time_stamp=1, nav_status=0))
    assert derived == []  # nobody reads events: none derived
    events = hub.events(maxlen=8)
    stores["a"].update(make_status(time_stamp=2, nav_status=1))
    stores["b"].link_changed(LinkState.STALE, LinkStale("silent", silent_for=1.0))
    with anyio.fail_after(WAIT):
        name, event = await anext(events)
        assert name == "a"
        assert isinstance(event, ev.NavigationOpened)
        name, event = await anext(events)
        assert name == "b"
        assert isinstance(event, ev.LinkStaleEvent)
    assert [type(e) for e in derived] == [ev.NavigationOpened]
    events.close()
    del events
    stores["a"].update(make_status(time_stamp=3, nav_status=0))
    assert len(derived) == 1  # nobody reads them again: none derived
    hub.close()


async def test_a_full_event_queue_drops_the_oldest() -> None:
    hub, stores = fleet_of("a")
    events = hub.events(maxlen=2)
    for index in range(5):
        stores["a"].link_changed(LinkState.LOST, ConnectionLost(str(index)))
        stores["a"].link_changed(LinkState.UP, None)
    assert events.dropped == 8
    hub.close()
