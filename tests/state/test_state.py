"""StatusStore: waiters, watches, newest-only streams, events and link errors (no I/O)."""

from __future__ import annotations

import asyncio
import gc
from typing import Any

import pytest

from galileo_async import events as ev
from galileo_async.errors import ConnectionLost, GalileoTimeout, LinkStale
from galileo_async.models import GalileoStatus, LinkState
from galileo_async.protocol import V2_DEFAULTS
from galileo_async.state import StatusStore
from galileo_async.state.listeners import Listeners

STEP = 2.0  # upper bound for anything that should happen at once


def st(time_stamp: int, **fields: Any) -> GalileoStatus:
    # A robot's status: all V2_DEFAULTS with 0 V would be the serial node's placeholder.
    return GalileoStatus(**{**V2_DEFAULTS, "power": 24.0, "time_stamp": time_stamp, **fields})


async def test_latest_status_and_clock() -> None:
    now = [10.0]
    store = StatusStore(clock=lambda: now[0])
    assert store.status is None
    assert store.last_update is None
    store.update(st(1))
    now[0] = 11.5
    store.update(st(2))
    assert store.status is not None
    assert store.status.time_stamp == 2
    assert store.last_update == 11.5


async def test_wait_until_is_level_triggered() -> None:
    store = StatusStore()
    store.update(st(1, nav_status=1))
    status = await store.wait_until(lambda s: s.navigating, timeout=0)
    assert status.time_stamp == 1


async def test_wait_until_wakes_on_the_matching_update() -> None:
    store = StatusStore()
    store.update(st(1))
    task = asyncio.create_task(store.wait_until(lambda s: s.navigating, timeout=STEP))
    await asyncio.sleep(0)
    store.update(st(2))
    await asyncio.sleep(0)
    assert not task.done()
    store.update(st(3, nav_status=1))
    assert (await asyncio.wait_for(task, STEP)).time_stamp == 3
    assert store._waiters == []


async def test_wait_until_timeout_carries_latest_status() -> None:
    store = StatusStore()
    store.update(st(7))
    with pytest.raises(GalileoTimeout) as info:
        await store.wait_until(lambda s: s.navigating, timeout=0.01)
    assert isinstance(info.value, TimeoutError)
    assert info.value.status is not None
    assert info.value.status.time_stamp == 7
    assert store._waiters == []


async def test_cancelled_wait_until_unregisters() -> None:
    store = StatusStore()
    task = asyncio.create_task(store.wait_until(lambda s: False))
    await asyncio.sleep(0)
    assert len(store._waiters) == 1
    task.cancel()
    with pytest.raises(asyncio.CancelledError):
        await task
    assert store._waiters == []


async def test_broken_predicate_fails_only_its_waiter() -> None:
    store = StatusStore()

    def broken(status: GalileoStatus) -> bool:
        raise KeyError("boom")

    bad = asyncio.create_task(store.wait_until(broken, timeout=STEP))
    good = asyncio.create_task(store.wait_until(lambda s: s.time_stamp == 1, timeout=STEP))
    await asyncio.sleep(0)
    store.update(st(1))  # must not raise into the link
    with pytest.raises(KeyError):
        await bad
    assert (await good).time_stamp == 1


@pytest.mark.parametrize("kind", ["lost", "stale"])
async def test_link_error_fails_waiters_at_once(kind: str) -> None:
    store = StatusStore()
    store.update(st(1))
    waiter = asyncio.create_task(store.wait_until(lambda s: False, timeout=60))
    with store.watch() as watch:
        reader = asyncio.create_task(watch.next(timeout=60))
        await asyncio.sleep(0)
        error: ConnectionLost | LinkStale
        if kind == "lost":
            error = ConnectionLost("unplugged")
            store.link_changed(LinkState.LOST, error)
        else:
            error = LinkStale("silent", silent_for=1.2)
            store.link_changed(LinkState.STALE, error)
        for task in (waiter, reader):
            with pytest.raises(type(error)):
                await asyncio.wait_for(task, STEP)
    assert store.link_error is error


async def test_wait_until_fails_fast_while_the_link_is_down_then_recovers() -> None:
    store = StatusStore()
    store.link_changed(LinkState.LOST, ConnectionLost("down"))
    with pytest.raises(ConnectionLost):
        await store.wait_until(lambda s: True, timeout=STEP)
    store.link_changed(LinkState.UP, None)
    assert store.link_error is None
    store.update(st(1))
    assert (await store.wait_until(lambda s: True, timeout=STEP)).time_stamp == 1


async def test_stale_then_fresh() -> None:
    store = StatusStore()
    store.link_changed(LinkState.STALE, LinkStale("silent", silent_for=1.0))
    with pytest.raises(LinkStale):
        await store.wait_until(lambda s: True)
    store.link_changed(LinkState.UP, None)
    store.update(st(1))
    assert (await store.wait_until(lambda s: True)).time_stamp == 1


async def test_watch_registers_before_send_and_sees_every_later_status() -> None:
    store = StatusStore()
    store.update(st(1))
    with store.watch() as watch:
        store.update(st(2))
        store.update(st(3))
        assert [(await watch.next(timeout=STEP)).time_stamp for _ in range(2)] == [2, 3]
        with pytest.raises(GalileoTimeout):
            await watch.next(timeout=0.01)
    store.update(st(4))
    assert not store._watches


async def test_watch_is_bounded_and_drops_oldest() -> None:
    store = StatusStore()
    with store.watch(maxlen=4) as watch:
        for stamp in range(1, 11):
            store.update(st(stamp))
        assert len(watch.buffer) == 4
        assert watch.dropped == 6
        assert [(await watch.next()).time_stamp for _ in range(4)] == [7, 8, 9, 10]


async def test_watch_delivers_buffered_statuses_before_the_error_then_continues() -> None:
    store = StatusStore()
    with store.watch() as watch:
        store.update(st(1))
        store.link_changed(LinkState.LOST, ConnectionLost("unplugged"))
        assert (await watch.next()).time_stamp == 1
        with pytest.raises(ConnectionLost):
            await watch.next()
        store.link_changed(LinkState.UP, None)
        store.update(st(2))
        assert (await watch.next(timeout=STEP)).time_stamp == 2


async def test_watch_created_while_down_fails_on_first_next() -> None:
    store = StatusStore()
    store.link_changed(LinkState.LOST, ConnectionLost("down"))
    with store.watch() as watch, pytest.raises(ConnectionLost):
        await watch.next(timeout=STEP)


async def test_watch_iteration_ends_on_store_close() -> None:
    store = StatusStore()
    watch = store.watch()
    received: list[int | None] = []

    async def consume() -> None:
        async for status in watch:
            received.append(status.time_stamp)

    task = asyncio.create_task(consume())
    store.update(st(1))
    store.update(st(2))
    await asyncio.sleep(0)
    store.close()
    await asyncio.wait_for(task, STEP)
    assert received == [1, 2]
    with pytest.raises(ConnectionLost):
        await watch.next()


async def test_statuses_newest_only_and_starts_with_latest() -> None:
    store = StatusStore()
    store.update(st(1))
    stream = store.statuses()
    assert (await anext(stream)).time_stamp == 1
    for stamp in range(2, 1000):
        store.update(st(stamp))
    # A consumer that fell behind gets the newest status, not a backlog.
    assert (await anext(stream)).time_stamp == 999
    waiting = asyncio.ensure_future(anext(stream))
    await asyncio.sleep(0)
    assert not waiting.done()
    store.update(st(1000))
    assert (await asyncio.wait_for(waiting, STEP)).time_stamp == 1000
    await stream.aclose()
    assert stream.dropped == 997  # skipped, never queued
    with pytest.raises(StopAsyncIteration):
        await anext(stream)


async def test_statuses_survive_reconnects_and_end_on_close() -> None:
    store = StatusStore()
    stream = store.statuses()
    store.update(st(1))
    assert (await anext(stream)).time_stamp == 1
    store.link_changed(LinkState.LOST, ConnectionLost("unplugged"))
    store.link_changed(LinkState.UP, None)
    store.update(st(1))  # the counter restarts after a reconnect
    assert (await anext(stream)).time_stamp == 1
    ending = asyncio.create_task(stream.next())  # next(): a coroutine, for tasks
    await asyncio.sleep(0)
    store.close()
    with pytest.raises(StopAsyncIteration):
        await asyncio.wait_for(ending, STEP)


async def test_many_independent_consumers() -> None:
    store = StatusStore()
    streams = [store.statuses() for _ in range(200)]
    slow = store.statuses()  # never read
    tasks = [asyncio.ensure_future(anext(s)) for s in streams]
    await asyncio.sleep(0)
    store.update(st(5))
    results = await asyncio.wait_for(asyncio.gather(*tasks), STEP)
    assert {r.time_stamp for r in results} == {5}
    store.update(st(6))
    assert (await anext(streams[0])).time_stamp == 6
    assert (await anext(slow)).time_stamp == 6


async def test_status_stream_is_listed_only_while_its_consumer_waits() -> None:
    store = StatusStore()
    stream = store.statuses()
    assert store._waiting_streams == []
    waiting = asyncio.ensure_future(anext(stream))
    await asyncio.sleep(0)
    assert store._waiting_streams == [stream]
    store.update(st(1))
    assert store._waiting_streams == []
    assert (await asyncio.wait_for(waiting, STEP)).time_stamp == 1
    for stamp in range(2, 100):
        store.update(st(stamp))  # a busy consumer: nothing per frame, nothing queued
    assert store._waiting_streams == []
    assert (await anext(stream)).time_stamp == 99
    assert stream.dropped == 97


async def test_status_stream_consumer_cancelled_while_waiting_gets_the_next_status() -> None:
    store = StatusStore()
    stream = store.statuses()
    for _ in range(3):  # cancelled waits do not pile up on the store
        with pytest.raises(TimeoutError):
            await asyncio.wait_for(anext(stream), 0.001)
    assert store._waiting_streams == [stream]
    waiting = asyncio.ensure_future(anext(stream))
    await asyncio.sleep(0)
    assert store._waiting_streams == [stream]
    store.update(st(7))
    assert (await asyncio.wait_for(waiting, STEP)).time_stamp == 7
    assert stream.dropped == 0


async def test_status_stream_consumer_cancelled_after_wakeup_keeps_the_status() -> None:
    store = StatusStore()
    stream = store.statuses()
    waiting = asyncio.ensure_future(anext(stream))
    await asyncio.sleep(0)
    waiting.cancel()
    store.update(st(3))  # the cancelled wait is skipped, the status stays unseen
    with pytest.raises(asyncio.CancelledError):
        await waiting
    assert (await anext(stream)).time_stamp == 3


async def test_status_stream_refuses_a_second_concurrent_consumer() -> None:
    store = StatusStore()
    stream = store.statuses()
    first = asyncio.ensure_future(anext(stream))
    await asyncio.sleep(0)
    with pytest.raises(RuntimeError, match="already waiting"):
        await anext(stream)
    store.update(st(1))
    assert (await asyncio.wait_for(first, STEP)).time_stamp == 1


async def test_status_stream_anext_is_a_future_and_next_a_coroutine() -> None:
    store = StatusStore()
    store.update(st(1))
    stream = store.statuses()
    ready = anext(stream)
    assert isinstance(ready, asyncio.Future)
    assert ready.done()  # the latest, at once
    assert (await ready).time_stamp == 1
    pending = anext(stream)
    assert isinstance(pending, asyncio.Future)
    assert not pending.done()
    store.update(st(2))
    assert (await asyncio.wait_for(pending, STEP)).time_stamp == 2
    task = asyncio.create_task(stream.next(timeout=STEP))
    await asyncio.sleep(0)
    store.update(st(3))
    assert (await task).time_stamp == 3
    stream.close()
    with pytest.raises(StopAsyncIteration):
        await stream.next()


async def test_status_stream_next_times_out_and_the_stream_goes_on() -> None:
    store = StatusStore()
    store.update(st(4))
    stream = store.statuses()
    assert (await stream.next(timeout=STEP)).time_stamp == 4
    with pytest.raises(GalileoTimeout) as caught:
        await stream.next(timeout=0.01)
    assert caught.value.status is not None
    assert caught.value.status.time_stamp == 4
    store.update(st(5))  # the timed-out wait is skipped; the status stays unseen
    assert (await stream.next(timeout=STEP)).time_stamp == 5
    assert stream.dropped == 0


def test_status_stream_follows_a_new_event_loop() -> None:
    store = StatusStore()
    stream = store.statuses()

    async def next_after_update(stamp: int) -> int | None:
        waiting = asyncio.ensure_future(anext(stream))
        await asyncio.sleep(0)
        store.update(st(stamp))
        return (await asyncio.wait_for(waiting, STEP)).time_stamp

    assert asyncio.run(next_after_update(1)) == 1
    # The first loop is closed: the stream's next wait belongs to the running one.
    assert asyncio.run(next_after_update(2)) == 2


async def test_status_stream_close_ends_a_waiting_consumer() -> None:
    store = StatusStore()
    stream = store.statuses()
    received: list[int | None] = []

    async def consume() -> None:
        async for status in stream:
            received.append(status.time_stamp)

    task = asyncio.create_task(consume())
    await asyncio.sleep(0)
    store.update(st(1))
    await asyncio.sleep(0)
    stream.close()
    await asyncio.wait_for(task, STEP)
    store.update(st(2))
    assert received == [1]
    with pytest.raises(StopAsyncIteration):
        await anext(stream)


async def test_status_stream_gives_the_unseen_latest_after_the_store_closes() -> None:
    store = StatusStore()
    stream = store.statuses()
    store.update(st(1))
    store.close()
    assert (await anext(stream)).time_stamp == 1
    with pytest.raises(StopAsyncIteration):
        await anext(stream)
    with pytest.raises(StopAsyncIteration):
        await anext(store.statuses())  # made after close: nothing


async def test_dropped_subscriptions_unregister_themselves() -> None:
    store = StatusStore()
    events, watch = store.events(), store.watch()
    assert len(store._event_streams) == len(store._watches) == 1
    # update() reads the snapshots the registries publish into the store's own slots.
    assert len(store._event_refs) == len(store._watch_refs) == 1
    del events, watch
    gc.collect()
    assert len(store._event_streams) == len(store._watches) == 0
    assert store._event_refs == store._watch_refs == ()
    kept = store.watch()
    kept.close()
    assert store._watch_refs == ()


async def test_slow_consumers_stay_bounded() -> None:
    store = StatusStore()
    never_read_stream = store.statuses()
    never_read_events = store.events(maxlen=8)
    with store.watch(maxlen=16) as never_read_watch:
        for stamp in range(1, 5001):
            store.update(st(stamp, busy_status=stamp % 2))
        assert len(never_read_watch.buffer) == 16
        assert len(never_read_events.buffer) == 8
        assert never_read_events.dropped == 4999 - 8
        assert (await anext(never_read_stream)).time_stamp == 5000
        assert never_read_stream.dropped == 4999


async def test_events_from_updates_and_link() -> None:
    store = StatusStore()
    stream = store.events()
    store.update(st(1, nav_status=0))
    store.update(st(2, nav_status=0))
    store.update(st(3, nav_status=1))
    store.link_changed(LinkState.STALE, LinkStale("quiet", silent_for=1.5))
    store.link_changed(LinkState.UP, None)
    store.link_changed(LinkState.LOST, ConnectionLost("unplugged"))
    store.link_changed(LinkState.LOST, ConnectionLost("still down"))  # no second event
    store.link_changed(LinkState.UP, None)
    got = [await asyncio.wait_for(anext(stream), STEP) for _ in range(5)]
    assert [type(e) for e in got] == [
        ev.NavigationOpened,
        ev.LinkStaleEvent,
        ev.LinkRestored,
        ev.ConnectionLostEvent,
        ev.ConnectionRestored,
    ]
    stale, lost = got[1], got[3]
    assert isinstance(stale, ev.LinkStaleEvent)
    assert stale.silent_for == 1.5
    assert isinstance(lost, ev.ConnectionLostEvent)
    assert "unplugged" in lost.reason
    assert got[0].status is not None
    assert got[0].status.time_stamp == 3
    store.close()
    with pytest.raises(StopAsyncIteration):
        await anext(stream)


async def test_events_with_custom_arrive_tolerance() -> None:
    store = StatusStore(arrive_tolerance=1.0)
    stream = store.events()
    # Navigation open: a goal shown under closed navigation does not run (docs/protocol.md §2.a).
    store.update(st(1, nav_status=1, target_num_id=2, target_status=1, target_distance=3.0))
    store.update(st(2, nav_status=1, target_num_id=2, target_status=0, target_distance=0.8))
    event = await asyncio.wait_for(anext(stream), 5)
    assert isinstance(event, ev.GoalReached)


async def test_close_is_idempotent_and_fails_everything() -> None:
    store = StatusStore()
    waiter = asyncio.create_task(store.wait_until(lambda s: False))
    await asyncio.sleep(0)
    store.close()
    store.close()
    with pytest.raises(ConnectionLost):
        await waiter
    with pytest.raises(ConnectionLost):
        await store.wait_until(lambda s: True)
    with pytest.raises(StopAsyncIteration):
        await anext(store.statuses())
    with pytest.raises(StopAsyncIteration):
        await anext(store.events())
    store.update(st(1))  # a late frame after close is harmless


def test_listeners_call_in_order_publish_each_snapshot_and_remove_one_addition() -> None:
    published: list[tuple[Any, ...]] = []
    listeners: Listeners[int] = Listeners("number", published.append)
    seen: list[str] = []

    def first(item: int) -> None:
        seen.append(f"first {item}")
        listeners.add(late)  # added while called: from the next item on

    def late(item: int) -> None:
        seen.append(f"late {item}")

    listeners.add(first)
    listeners.add(first)  # twice: called twice
    listeners.call(1)
    assert seen == ["first 1", "first 1"]
    assert len(listeners) == 4
    listeners.remove(first)  # one addition of it
    listeners.remove(print)  # not one: nothing changes
    assert listeners.snapshot == (first, late, late)
    assert published == [(first,), (first, first), (first, first, late), (first, first, late, late),
                         (first, late, late)]  # fmt: skip
    seen.clear()
    listeners.call(2)
    assert seen == ["first 2", "late 2", "late 2"]


def test_a_listener_that_raises_is_logged_and_stops_none(caplog: pytest.LogCaptureFixture) -> None:
    listeners: Listeners[int] = Listeners("number", lambda _snapshot: None)
    seen: list[int] = []

    def broken(_item: int) -> None:
        raise RuntimeError("a broken listener")

    listeners.add(broken)
    listeners.add(seen.append)
    listeners.call(7)
    assert seen == [7]
    assert "number listener" in caplog.text
    assert "a broken listener" in caplog.text
