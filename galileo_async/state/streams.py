"""Subscriptions of the state store: watches, status streams and event streams (no I/O).

The store feeds them through ``offer``, ``fail`` and ``close`` only, and they read the store
through StatusSource: this module imports nothing of the store.
"""

from __future__ import annotations

import asyncio
import weakref
from collections import deque
from collections.abc import Callable, Iterator
from types import TracebackType
from typing import Any, Generic, Protocol, TypeVar

from ..errors import ConnectionLost, GalileoConnectionError, GalileoError, GalileoTimeout
from ..events import Event
from ..models import GalileoStatus
from .waiters import expire

__all__ = [
    "BoundedQueue",
    "EventStream",
    "StatusSource",
    "StatusStream",
    "Subscribers",
    "Subscription",
    "Watch",
    "offer_to_waiting",
    "offer_to_watches",
]

_running_loop = asyncio.get_running_loop
InvalidStateError = asyncio.InvalidStateError

_T = TypeVar("_T")
_T_contra = TypeVar("_T_contra", contravariant=True)


class StatusSource(Protocol):
    """What a subscription reads of its store (StatusStore is one)."""

    @property
    def status(self) -> GalileoStatus | None:
        """The latest robot status, None before the first one."""

    @property
    def updates(self) -> int:
        """How many statuses the store has recorded."""

    @property
    def closed(self) -> bool:
        """True once the store is closed."""


class Subscription(Protocol[_T_contra]):
    """What the store calls on a queued subscription: offer an item, fail it, close it."""

    def offer(self, item: _T_contra) -> None:
        """Take ``item`` (hot path; never raises)."""

    def fail(self, exc: GalileoConnectionError) -> None:
        """Report a link error to the consumer."""

    def close(self) -> None:
        """End the subscription; buffered items stay readable."""


class BoundedQueue(Generic[_T]):
    """A bounded FIFO async iterator with one wake-up future: the core of every subscription.

    ``offer`` queues (the oldest is dropped when full, counted in ``dropped``), ``close``
    ends it once drained; ``registry`` is the Subscribers it leaves on close.
    """

    __slots__ = ("__weakref__", "_registry", "_wakeup", "buffer", "closed", "dropped", "error")

    def __init__(self, registry: Subscribers[Any], maxlen: int) -> None:
        if maxlen < 1:
            raise ValueError(f"maxlen must be at least 1, got {maxlen}")
        self._registry = registry
        self.buffer: deque[_T] = deque(maxlen=maxlen)
        # Resolved with None to look at the queue again, or (watches) with the item itself
        # when the consumer was waiting on an empty queue.
        self._wakeup: asyncio.Future[_T | None] | None = None
        self.dropped = 0
        self.closed = False
        self.error: GalileoConnectionError | None = None

    def offer(self, item: _T) -> None:
        """Queue ``item`` (the oldest is dropped when full) and wake the consumer."""
        buffer = self.buffer
        if len(buffer) == buffer.maxlen:
            self.dropped += 1
        buffer.append(item)
        self._wake()

    def fail(self, exc: GalileoConnectionError) -> None:
        """Raise ``exc`` to the consumer once (watches; other queues only wake)."""
        self.error = exc
        self._wake()

    def _wake(self) -> None:
        wakeup = self._wakeup
        if wakeup is not None and not wakeup.done():
            wakeup.set_result(None)

    async def _wait(self, timeout: float | None) -> _T | None:
        """The item handed over, or None once something is buffered, failed or closed."""
        loop = asyncio.get_running_loop()
        wakeup: asyncio.Future[_T | None] = loop.create_future()
        self._wakeup = wakeup
        timer = None if timeout is None else loop.call_later(timeout, expire, wakeup)
        try:
            return await wakeup
        finally:
            self._wakeup = None
            if timer is not None:
                timer.cancel()

    def __aiter__(self) -> BoundedQueue[_T]:
        return self

    async def __anext__(self) -> _T:
        buffer = self.buffer
        while True:
            if buffer:
                return buffer.popleft()
            if self.closed:
                raise StopAsyncIteration
            # _wait(None) inlined: one coroutine frame less on every status of every stream.
            # No clean-up needed: whoever wakes it clears _wakeup, and a cancelled future
            # left behind is done, which every waker allows for.
            self._wakeup = wakeup = _running_loop().create_future()
            await wakeup  # nothing hands an item over here: only watches get handoffs

    def close(self) -> None:
        """Stop receiving (idempotent); what is buffered can still be read."""
        self._registry.discard(self)
        self.closed = True
        self._wake()

    async def aclose(self) -> None:
        """Same as close(), for ``contextlib.aclosing``."""
        self.close()


class Subscribers(Generic[_T]):
    """Weakly held subscriptions: one a consumer dropped unregisters itself when collected."""

    __slots__ = ("_by_id", "_publish", "refs")

    def __init__(
        self, publish: Callable[[tuple[weakref.ref[_T], ...]], None] | None = None
    ) -> None:
        """``publish(refs)`` is called with every new snapshot of ``refs``."""
        self._by_id: dict[int, weakref.ref[_T]] = {}
        # An immutable snapshot for the hot path: iterating it never races a removal.
        self.refs: tuple[weakref.ref[_T], ...] = ()
        self._publish = publish

    def add(self, item: _T) -> None:
        key = id(item)
        self._by_id[key] = weakref.ref(item, lambda _ref: self._forget(key))
        self._set_refs(tuple(self._by_id.values()))

    def discard(self, item: _T) -> None:
        self._forget(id(item))

    def _forget(self, key: int) -> None:
        if self._by_id.pop(key, None) is not None:
            self._set_refs(tuple(self._by_id.values()))

    def clear(self) -> None:
        self._by_id.clear()
        self._set_refs(())

    def _set_refs(self, refs: tuple[weakref.ref[_T], ...]) -> None:
        self.refs = refs
        if self._publish is not None:
            self._publish(refs)

    def __len__(self) -> int:
        return len(self._by_id)

    def __iter__(self) -> Iterator[_T]:
        for ref in self.refs:
            item = ref()
            if item is not None:
                yield item


class Watch(BoundedQueue[GalileoStatus]):
    """Every status after registration (bounded: oldest dropped); raises pushed link errors."""

    __slots__ = ("_source", "halted")

    def __init__(self, source: StatusSource, registry: Subscribers[Any], maxlen: int) -> None:
        super().__init__(registry, maxlen)
        self._source = source
        #: Raised by every next() from halt() on, before any buffered status.
        self.halted: GalileoError | None = None

    def halt(self, exc: GalileoError) -> None:
        """End the watch with ``exc`` now: next() raises it, buffered statuses unread (stop())."""
        self.halted = exc
        self._wake()

    async def next(self, timeout: float | None = None) -> GalileoStatus:
        """The next status; GalileoTimeout after ``timeout`` s, link errors as pushed."""
        while True:
            if self.halted is not None:
                raise self.halted
            if self.buffer:
                return self.buffer.popleft()
            if self.error is not None:
                error, self.error = self.error, None
                raise error
            if self.closed:
                raise ConnectionLost("the watch is closed (or its status store is)")
            try:
                handed = await self._wait(timeout)
            except TimeoutError:
                status = self._source.status
                raise GalileoTimeout(f"no status within {timeout} s", status=status) from None
            if handed is not None:
                return handed

    def __enter__(self) -> Watch:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    async def __anext__(self) -> GalileoStatus:
        try:
            return await self.next()
        except ConnectionLost:
            if self.closed and not self.buffer:
                raise StopAsyncIteration from None
            raise


class EventStream(BoundedQueue[Event]):
    """Async iterator of events (bounded queue: oldest dropped); ends when the store closes."""

    __slots__ = ()


class StatusStream:
    """Async iterator of the newest status only: a slow consumer skips to the newest one.

    Not a queue: a cursor over the store's latest status. Only a consumer that is waiting
    is known to the store, so a stream costs nothing per frame while its consumer is busy,
    and a waiting consumer is handed the status itself (no buffer).
    """

    __slots__ = ("_loop", "_seen", "_store", "_waiting", "_wakeup", "closed", "dropped")

    def __init__(self, store: StatusSource, waiting: list[StatusStream]) -> None:
        """``waiting``: the store's list of streams to offer the next status to."""
        self._store = store
        self._waiting = waiting
        # The store's update count when this stream last handed out a status; one behind
        # while a status exists, so the first item is the latest status.
        self._seen = store.updates - 1 if store.status is not None else store.updates
        # While set, the stream is on ``waiting``.
        self._wakeup: asyncio.Future[GalileoStatus] | None = None
        self.dropped = 0
        self.closed = store.closed
        # The loop of its last wait: on CPython 3.11, asking asyncio for the running loop
        # makes a getpid() system call, about 0.1 µs per status a waiting consumer takes.
        self._loop: asyncio.AbstractEventLoop | None = None

    def __aiter__(self) -> StatusStream:
        return self

    def __anext__(self) -> asyncio.Future[GalileoStatus]:
        """A future of the next status; a Future, not a coroutine: for a task use ``next()``."""
        # Not a coroutine: `async for` then awaits the future itself, with no coroutine
        # object made and driven per status, about 0.25 µs per status a consumer takes.
        if self.closed:
            raise StopAsyncIteration
        store = self._store
        updates = store.updates
        status = store.status
        # None after a status: placeholder frames (a restarted serial node) came since.
        if updates != self._seen and status is not None:
            self.dropped += updates - self._seen - 1
            self._seen = updates
            # The consumer was busy, not waiting: asked for the loop as plain asyncio does.
            ready: asyncio.Future[GalileoStatus] = _running_loop().create_future()
            ready.set_result(status)
            return ready
        if store.closed:
            self.closed = True
            raise StopAsyncIteration
        wakeup = self._wakeup
        if wakeup is not None and not wakeup.done():
            raise RuntimeError("another task is already waiting on this status stream")
        loop = self._loop
        if loop is None or loop.is_closed():  # first wait, or a new asyncio.run()
            loop = self._loop = _running_loop()
        fresh: asyncio.Future[GalileoStatus] = loop.create_future()
        self._wakeup = fresh
        if wakeup is None:
            self._waiting.append(self)
        # else: its last wait was cancelled and the store still lists it: only the future
        # is new. The store's offer_to_waiting hands it the next status and unlists it.
        return fresh

    async def next(self, timeout: float | None = None) -> GalileoStatus:
        """The next status, as iterating gives it; GalileoTimeout after ``timeout`` s.

        A coroutine (``asyncio.create_task(stream.next())`` works); StopAsyncIteration once
        the stream has ended.
        """
        future = self.__anext__()
        if timeout is None:
            return await future
        try:
            return await asyncio.wait_for(future, timeout)
        except asyncio.TimeoutError:
            status = self._store.status
            raise GalileoTimeout(f"no new status within {timeout} s", status=status) from None

    def close(self) -> None:
        """Stop iterating (idempotent): a waiting consumer and every later step end."""
        self.closed = True
        wakeup = self._wakeup
        self._wakeup = None
        if wakeup is not None and not wakeup.done():
            wakeup.set_exception(StopAsyncIteration())

    async def aclose(self) -> None:
        """Same as close(), for ``contextlib.aclosing``."""
        self.close()


# The store's hot path: one call per frame offers a status to every subscriber of a kind.
# A method call per subscriber instead cost 0.14 µs a frame with four subscribers
# (`python -m benchmarks ingest --quick`, medians of 8 interleaved runs).


def offer_to_watches(refs: tuple[weakref.ref[Watch], ...], status: GalileoStatus) -> None:
    """Watch.offer(status) for every live watch of ``refs``; a waiting consumer is handed it."""
    for ref in refs:
        watch = ref()
        if watch is not None:
            wakeup = watch._wakeup
            if wakeup is not None:
                watch._wakeup = None
                try:
                    # Its consumer waits, so nothing is buffered: hand the status over.
                    wakeup.set_result(status)
                    continue
                except InvalidStateError:
                    pass  # woken already or cancelled: queue the status
            buffer = watch.buffer
            if len(buffer) == buffer.maxlen:
                watch.dropped += 1
            buffer.append(status)


def offer_to_waiting(streams: list[StatusStream], status: GalileoStatus, seen: int) -> None:
    """Hand ``status``, the store's ``seen``-th, to every stream in ``streams``, then empty it."""
    # A wake-up future is rarely done already (a cancelled wait): asking done() first
    # would cost a call per stream on every frame, the try nothing.
    for stream in streams:
        wakeup = stream._wakeup
        stream._wakeup = None
        if wakeup is not None:
            try:
                wakeup.set_result(status)
            except InvalidStateError:
                continue  # its wait was cancelled or ended: the status stays unseen
            stream._seen = seen
    # Emptied in place, not replaced: every stream holds this list, set_result only
    # schedules callbacks (no stream joins meanwhile), and a fleet frees no list per frame.
    streams.clear()
