"""A fleet's merged streams: one iterator over every robot, coalesced per robot (no I/O).

Each robot calls the hub's listener synchronously on every status (Robot.add_update_listener):
it marks the robot in each merged stream's dirty set and wakes that stream's consumer, if
it waits. No task per robot runs per frame, and a slow consumer finds each robot once, with
its newest status, however many frames came meanwhile.
"""

from __future__ import annotations

import asyncio
import weakref
from collections.abc import Callable, Iterable
from typing import Protocol

from ..events import Event
from ..models import GalileoStatus
from ..state import BoundedQueue, Subscribers

__all__ = [
    "DEFAULT_FLEET_EVENT_QUEUE",
    "FleetEventStream",
    "FleetHub",
    "FleetStatusStream",
    "StatusFeed",
]

#: (name, event) pairs a fleet events() consumer keeps before it drops the oldest.
DEFAULT_FLEET_EVENT_QUEUE = 4096


class StatusFeed(Protocol):
    """What the hub reads of one robot (a Robot; a StatusStore in tests): public API only."""

    @property
    def status(self) -> GalileoStatus | None:
        """The latest status, None before the first."""

    def add_update_listener(self, listener: Callable[[GalileoStatus], None]) -> None:
        """Call ``listener`` with every later status."""

    def remove_update_listener(self, listener: Callable[[GalileoStatus], None]) -> None:
        """Stop calling ``listener``."""

    def add_event_listener(self, listener: Callable[[Event], None]) -> None:
        """Call ``listener`` with every later event."""

    def remove_event_listener(self, listener: Callable[[Event], None]) -> None:
        """Stop calling ``listener``."""


class FleetStatusStream:
    """Async iterator of ``(name, status)`` over a fleet: each robot's newest, never a backlog.

    A robot is listed at most once until its consumer takes it, and the status handed out is
    the newest at that moment. The first items are the latest status of every robot.
    """

    __slots__ = ("__weakref__", "_batch", "_dirty", "_hub", "_index", "_wakeup", "closed")

    def __init__(self, hub: FleetHub) -> None:
        self._hub = hub
        # Ordered set of robots with a status not yet handed out.
        self._dirty: dict[str, None] = dict.fromkeys(
            name for name, store in hub.stores.items() if store.status is not None
        )
        # The names taken from _dirty for this pass, and how far the consumer got.
        self._batch: list[str] = []
        self._index = 0
        self._wakeup: asyncio.Future[None] | None = None
        self.closed = hub.closed

    def _mark(self, name: str) -> None:
        """``name`` has a new status (FleetHub's listener does the same inline)."""
        self._dirty[name] = None
        if self._wakeup is not None:
            self._wake()

    def _wake(self) -> None:
        """Wake the waiting consumer (once: the future is dropped)."""
        wakeup = self._wakeup
        self._wakeup = None
        # A cancelled wait leaves a done future: the names stay marked for the next one.
        if wakeup is not None and not wakeup.done():
            wakeup.set_result(None)

    def __aiter__(self) -> FleetStatusStream:
        return self

    async def __anext__(self) -> tuple[str, GalileoStatus]:
        stores = self._hub.stores
        while True:
            batch, index = self._batch, self._index
            while index < len(batch):
                name = batch[index]
                index += 1
                store = stores.get(name)
                status = None if store is None else store.status
                if status is not None:
                    self._index = index
                    # Marked again since the pass began: this newest status covers it.
                    self._dirty.pop(name, None)
                    return name, status
            if self._dirty:
                self._batch = list(self._dirty)
                self._dirty.clear()
                self._index = 0
                continue
            self._batch, self._index = [], 0
            if self.closed:
                raise StopAsyncIteration
            wakeup = self._wakeup
            if wakeup is not None and not wakeup.done():
                raise RuntimeError("another task is already waiting on this fleet stream")
            self._wakeup = wakeup = asyncio.get_running_loop().create_future()
            try:
                await wakeup
            finally:
                self._wakeup = None

    def pending(self) -> int:
        """How many robots have a status this stream has not handed out yet."""
        return len(self._dirty) + len(self._batch) - self._index

    def close(self) -> None:
        """Stop iterating (idempotent): a waiting consumer and every later step end."""
        self._hub.status_streams.discard(self)
        self._end()

    def _end(self) -> None:
        self.closed = True
        wakeup = self._wakeup
        if wakeup is not None and not wakeup.done():
            wakeup.set_result(None)

    async def aclose(self) -> None:
        """Same as close(), for ``contextlib.aclosing``."""
        self.close()


class FleetEventStream(BoundedQueue[tuple[str, Event]]):
    """Async iterator of ``(name, event)`` over a fleet (bounded: the oldest is dropped)."""

    __slots__ = ()


class FleetHub:
    """The fleet's robots by name and its merged streams; their listeners feed it."""

    def __init__(self) -> None:
        #: The robots (their feeds) by name.
        self.stores: dict[str, StatusFeed] = {}
        # The listeners given to each feed, to take back on detach.
        self._status_listeners: dict[str, Callable[[GalileoStatus], None]] = {}
        self._event_listeners: dict[str, Callable[[Event], None]] = {}
        self.closed = False
        self.status_streams: Subscribers[FleetStatusStream] = Subscribers(self._set_status_refs)
        self.event_streams: Subscribers[FleetEventStream] = Subscribers(self._set_event_refs)
        self._status_refs: tuple[weakref.ref[FleetStatusStream], ...] = ()
        self._listening_events = False

    def attach(self, name: str, store: StatusFeed) -> None:
        """Feed this hub from ``store`` (a robot of the fleet that connected)."""
        self.stores[name] = store
        listener = self._status_listeners[name] = self._status_listener(name)
        store.add_update_listener(listener)
        if self._listening_events:
            self._listen_events(name, store)
        if store.status is not None:
            self._mark(name)

    def detach(self, name: str) -> None:
        """Stop listening to ``name``'s robot."""
        store = self.stores.pop(name, None)
        if store is not None:
            store.remove_update_listener(self._status_listeners.pop(name))
            self._unlisten_events(name, store)

    def _listen_events(self, name: str, store: StatusFeed) -> None:
        listener = self._event_listeners[name] = self._event_listener(name)
        store.add_event_listener(listener)

    def _unlisten_events(self, name: str, store: StatusFeed) -> None:
        listener = self._event_listeners.pop(name, None)
        if listener is not None:
            store.remove_event_listener(listener)

    def _status_listener(self, name: str) -> Callable[[GalileoStatus], None]:
        def on_update(_status: GalileoStatus) -> None:
            # FleetStatusStream._mark inlined: this runs on every frame of every robot.
            for ref in self._status_refs:
                stream = ref()
                if stream is not None:
                    stream._dirty[name] = None
                    if stream._wakeup is not None:
                        stream._wake()

        return on_update

    def _event_listener(self, name: str) -> Callable[[Event], None]:
        def on_event(event: Event) -> None:
            for stream in self.event_streams:
                stream.offer((name, event))

        return on_event

    def _mark(self, name: str) -> None:
        for stream in self.status_streams:
            stream._mark(name)

    def statuses(self) -> FleetStatusStream:
        """A new merged status stream (starts with every robot's latest status)."""
        stream = FleetStatusStream(self)
        if not self.closed:
            self.status_streams.add(stream)
        return stream

    def events(self, maxlen: int) -> FleetEventStream:
        """A new merged event stream of events after now."""
        # A fleet's event stream spans many stores: it has none of its own.
        stream = FleetEventStream(self.event_streams, maxlen)
        if self.closed:
            stream.close()
        else:
            self.event_streams.add(stream)
        return stream

    def close(self) -> None:
        """End every merged stream (idempotent)."""
        self.closed = True
        for stream in self.status_streams:
            stream._end()
        for events in self.event_streams:
            events.close()
        self.status_streams.clear()
        self.event_streams.clear()
        for name in list(self.stores):
            self.detach(name)

    def _set_status_refs(self, refs: tuple[weakref.ref[FleetStatusStream], ...]) -> None:
        self._status_refs = refs

    def _set_event_refs(self, refs: Iterable[object]) -> None:
        # Events are derived per frame only while somebody reads them.
        listening = bool(tuple(refs))
        if listening == self._listening_events:
            return
        self._listening_events = listening
        for name, store in self.stores.items():
            if listening:
                self._listen_events(name, store)
            else:
                self._unlisten_events(name, store)
