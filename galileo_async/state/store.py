"""StatusStore: the latest status, waiters on predicates, subscriptions and events (no I/O)."""

from __future__ import annotations

import asyncio
import logging
import time
import weakref
from collections.abc import Callable
from operator import attrgetter
from typing import Any, TypeVar

from .. import events as ev
from ..errors import ConnectionLost, GalileoConnectionError, GalileoTimeout, LinkStale
from ..events import Event
from ..models import GalileoStatus, LinkState, _wire_power
from ..transitions import DEFAULT_ARRIVE_TOLERANCE, GoalMachine, SentGoal, step_events
from .listeners import EventListener, Listeners, StatusListener
from .streams import (
    EventStream,
    StatusStream,
    Subscribers,
    Subscription,
    Watch,
    offer_to_waiting,
    offer_to_watches,
)
from .waiters import Waiter, expire, fail_with

__all__ = [
    "DEFAULT_EVENT_QUEUE",
    "DEFAULT_WATCH_QUEUE",
    "EventStream",
    "StatusStore",
    "StatusStream",
    "Watch",
]

_log = logging.getLogger(__name__)

#: Statuses a Watch keeps before it drops the oldest.
DEFAULT_WATCH_QUEUE = 256
#: Events an events() consumer keeps before it drops the oldest.
DEFAULT_EVENT_QUEUE = 1024

# Only these fields can produce an event; time_stamp, speeds, pose, power and distance
# change on nearly every frame, so frames that differ only in them skip derive_events.
_EVENT_KEY = attrgetter(
    "nav_status", "visual_status", "map_status", "charge_status", "loop_status",
    "target_num_id", "target_status", "busy_status",
)  # fmt: skip

_Sub = TypeVar("_Sub", bound="Subscription[Any]")


class StatusStore:
    """Latest status and everything that waits on it; fed synchronously by the link."""

    # Slots keep the attributes update() reads 30 times a second inside the object: one
    # memory block less to fetch per frame, which counts across a fleet (BENCHMARKS.md §2).
    __slots__ = (
        "__weakref__", "_clock", "_event_calls", "_event_key", "_event_listeners", "_event_refs",
        "_event_streams", "_frame_waiters", "_goal", "_link_error", "_status_hooks",
        "_update_calls", "_update_listeners", "_update_one", "_waiters", "_waiting_streams",
        "_watch_refs", "_watches", "closed", "last_update", "placeholder_frames", "status",
        "updates",
    )  # fmt: skip

    def __init__(
        self,
        *,
        clock: Callable[[], float] = time.monotonic,
        arrive_tolerance: float = DEFAULT_ARRIVE_TOLERANCE,
    ) -> None:
        self.status: GalileoStatus | None = None
        #: How many statuses update() has recorded.
        self.updates = 0
        #: Placeholder frames of the vendor's serial node seen (GalileoStatus.is_placeholder).
        self.placeholder_frames = 0
        self.last_update: float | None = None
        self.closed = False
        self._clock = clock
        self._event_key: tuple[Any, ...] | None = None
        # The goal rule with its memory (transitions.GoalMachine), as each goto keeps one;
        # its `sent`: the goal this process sent and the rule still tracks (track_goal).
        self._goal = GoalMachine(arrive_tolerance=arrive_tolerance)
        self._waiters: list[Waiter] = []
        # Weak: a subscription its consumer dropped unregisters itself when collected.
        # update() reads the registries' snapshots from the store's own slots: at 1000
        # robots, two objects fewer touched per frame (BENCHMARKS.md §2).
        self._watch_refs: tuple[weakref.ref[Watch], ...] = ()
        self._watches: Subscribers[Watch] = Subscribers(self._set_watch_refs)
        # Only streams whose consumer waits: the others read `status` when they ask.
        self._waiting_streams: list[StatusStream] = []
        self._event_refs: tuple[weakref.ref[EventStream], ...] = ()
        self._event_streams: Subscribers[EventStream] = Subscribers(self._set_event_refs)
        # The listeners, and their snapshots in the store's own slots, as for subscriptions;
        # _update_one is the only status listener when there is exactly one (a fleet's):
        # called without a loop, per frame of every robot (BENCHMARKS.md §2).
        self._update_calls: tuple[StatusListener, ...] = ()
        self._update_one: StatusListener | None = None
        self._update_listeners: Listeners[GalileoStatus] = Listeners(
            "status", self._set_update_calls
        )
        self._event_calls: tuple[EventListener, ...] = ()
        self._event_listeners: Listeners[Event] = Listeners("event", self._set_event_calls)
        self._link_error: GalileoConnectionError | None = None
        # Futures of first_frame(): resolved by any valid frame, placeholders included.
        self._frame_waiters: list[asyncio.Future[None]] = []
        # One-shot callbacks of call_on_next_status().
        self._status_hooks: list[Callable[[GalileoStatus], None]] = []

    @property
    def awaiting_robot(self) -> bool:
        """True while frames arrive but only the serial node's placeholders: no robot status."""
        return self.status is None and self.placeholder_frames > 0

    @property
    def link_error(self) -> GalileoConnectionError | None:
        """The error the link reported and has not cleared yet (lost or stale), else None."""
        return self._link_error

    # --- fed by the link --------------------------------------------------------------

    def update(self, status: GalileoStatus) -> None:
        """Record a new status and wake whatever waits on it (hot path; never raises)."""
        # power's wire value: the field reads it through float32_decimal, a conversion
        # this test for zero, on every frame, does not need.
        if _wire_power(status) == 0.0 and status.is_placeholder:
            self._placeholder()
            return
        if self._frame_waiters:
            self._wake_frame_waiters()
        if self._event_refs or self._event_calls:
            key = _EVENT_KEY(status)
            if key == self._event_key:
                self._goal.see(status)  # no field that makes an event changed
            else:
                prev = self.status
                if prev is None:
                    self._goal.start(status)
                else:
                    if self._event_key is None:  # the first status since somebody listens
                        self._goal.start(prev)
                    for event in step_events(prev, status, self._goal.step(status)):
                        self._emit(event)
                self._event_key = key
        self.status = status
        self.updates = updates = self.updates + 1
        self.last_update = self._clock()
        if self._status_hooks:
            self._run_status_hooks(status)
        if self._waiters:
            self._check_waiters(status)
        if self._waiting_streams:
            offer_to_waiting(self._waiting_streams, status, updates)
        if self._watch_refs:
            offer_to_watches(self._watch_refs, status)
        one = self._update_one
        if one is not None:
            try:
                one(status)
            except Exception:
                _log.exception("status listener %r failed", one)
        elif self._update_calls:
            self._update_listeners.call(status)

    def _placeholder(self) -> None:
        """A placeholder frame: the link is up, but the robot's state is unknown (again)."""
        self.placeholder_frames += 1
        if self.status is not None:
            _log.info("placeholder frames: the navigation system has not reported (again)")
            # The serial node restarted: its last status is not the robot's state any more.
            self.status = None
            self._event_key = None
        if self._frame_waiters:
            self._wake_frame_waiters()

    # --- hooks for the robot layer: its one-shot callbacks, the goal it tracks, its events -

    def call_on_next_status(self, callback: Callable[[GalileoStatus], None]) -> None:
        """Call ``callback`` once with the next robot status (placeholders are not one)."""
        if not self.closed:
            self._status_hooks.append(callback)

    def track_goal(self, sent: SentGoal) -> None:
        """This process writes ``g N`` now: events() attributes later frames by the goal rule."""
        self._goal.sent = sent

    def revise_tracked_goal(
        self, origin: object, revise: Callable[[SentGoal], SentGoal | None]
    ) -> None:
        """Apply ``revise`` to the tracked goal if ``origin`` sent it (None: track nothing)."""
        sent = self._goal.sent
        if sent is not None and sent.origin is origin:
            self._goal.sent = revise(sent)

    def emit(self, event: Event) -> None:
        """Hand ``event``, one the driver itself caused, to every events() consumer."""
        self._emit(event)

    def _run_status_hooks(self, status: GalileoStatus) -> None:
        hooks, self._status_hooks = self._status_hooks, []
        for hook in hooks:
            try:
                hook(status)
            except Exception:  # a broken hook must not stop the status stream
                _log.exception("status hook %r failed", hook)

    def _wake_frame_waiters(self) -> None:
        waiters, self._frame_waiters = self._frame_waiters, []
        for future in waiters:
            if not future.done():
                future.set_result(None)

    def link_changed(self, state: LinkState, error: GalileoConnectionError | None) -> None:
        """LOST or STALE fail every waiter and watch with ``error``; each event once per spell."""
        # LOST comes again at each further drop of one outage (a reopened port that died).
        if state is LinkState.LOST and error is not None:
            was_lost = isinstance(self._link_error, ConnectionLost)
            self._link_error = error
            self._fail_all(error)
            if not was_lost:
                self._emit(ev.ConnectionLostEvent(status=self.status, reason=str(error)))
        elif state is LinkState.STALE and isinstance(error, LinkStale):
            if self._link_error is not None:
                return
            self._link_error = error
            self._fail_all(error)
            self._emit(ev.LinkStaleEvent(status=self.status, silent_for=error.silent_for))
        elif state is LinkState.UP:
            previous, self._link_error = self._link_error, None
            if isinstance(previous, ConnectionLost):
                self._emit(ev.ConnectionRestored(status=self.status))
            elif isinstance(previous, LinkStale):
                self._emit(ev.LinkRestored(status=self.status))

    def close(self) -> None:
        """End every iterator; fail every waiter with the drop that ended the link, if any."""
        if self.closed:
            return
        self.closed = True
        self._status_hooks = []
        closed = self._closed_error()
        self._fail_waiters(closed)
        frame_waiters, self._frame_waiters = self._frame_waiters, []
        for future in frame_waiters:
            if not future.done():
                future.set_exception(closed)
        for subscriptions in (self._watches, self._event_streams):
            for subscription in subscriptions:
                subscription.close()
        self._watches.clear()
        self._event_streams.clear()
        # Emptied in place: every stream holds this list.
        waiting = list(self._waiting_streams)
        self._waiting_streams.clear()
        for stream in waiting:
            stream.close()

    # --- used by robot and users -------------------------------------------------------

    def add_update_listener(self, listener: StatusListener) -> None:
        """Call ``listener(status)`` with every later recorded status (placeholders are not)."""
        self._update_listeners.add(listener)

    def remove_update_listener(self, listener: StatusListener) -> None:
        """Stop calling ``listener`` (no-op if it is not one)."""
        self._update_listeners.remove(listener)

    def add_event_listener(self, listener: EventListener) -> None:
        """Call ``listener(event)`` with every later event; events are derived while any listens."""
        self._event_listeners.add(listener)

    def remove_event_listener(self, listener: EventListener) -> None:
        """Stop calling ``listener`` (no-op if it is not one)."""
        self._event_listeners.remove(listener)

    async def wait_until(
        self, predicate: Callable[[GalileoStatus], bool], timeout: float | None = None,
        *, abort: asyncio.Future[Any] | None = None,
    ) -> GalileoStatus:  # fmt: skip
        """First status (latest included) matching ``predicate``; GalileoTimeout; abort's error."""
        self._raise_if_unusable()
        status = self.status
        if status is not None and predicate(status):
            return status
        loop = asyncio.get_running_loop()
        future: asyncio.Future[GalileoStatus] = loop.create_future()
        waiter = Waiter(predicate, future)
        self._waiters.append(waiter)
        timer = None if timeout is None else loop.call_later(timeout, expire, future)
        unlink = fail_with(future, abort)
        try:
            return await future
        except TimeoutError:
            raise GalileoTimeout(
                f"status did not match within {timeout} s", status=self.status
            ) from None
        finally:
            unlink()
            if timer is not None:
                timer.cancel()
            if waiter in self._waiters:
                self._waiters.remove(waiter)

    async def first_frame(self, timeout: float | None) -> None:
        """Return once a valid frame (a placeholder too) came; stale or lost links do not end it."""
        if self.closed:
            raise self._closed_error()
        if self.status is not None or self.placeholder_frames:
            return
        loop = asyncio.get_running_loop()
        future: asyncio.Future[None] = loop.create_future()
        self._frame_waiters.append(future)
        timer = None if timeout is None else loop.call_later(timeout, expire, future)
        try:
            await future
        except TimeoutError:
            raise GalileoTimeout(f"no valid frame within {timeout} s") from None
        finally:
            if timer is not None:
                timer.cancel()
            if future in self._frame_waiters:
                self._frame_waiters.remove(future)

    def watch(self, *, maxlen: int = DEFAULT_WATCH_QUEUE) -> Watch:
        """Register now (before sending) for every later status; a context manager."""
        watch = self._subscribe(Watch(self, self._watches, maxlen), self._watches)
        if self._link_error is not None and not self.closed:
            watch.fail(self._link_error)
        return watch

    def statuses(self) -> StatusStream:
        """Newest-only async iterator (starts with the latest); survives reconnects."""
        return StatusStream(self, self._waiting_streams)

    def events(self, *, maxlen: int = DEFAULT_EVENT_QUEUE) -> EventStream:
        """Async iterator of events after now (bounded queue); ends when the store closes."""
        return self._subscribe(EventStream(self._event_streams, maxlen), self._event_streams)

    # --- internals ---------------------------------------------------------------------

    def _set_watch_refs(self, refs: tuple[weakref.ref[Watch], ...]) -> None:
        self._watch_refs = refs

    def _set_update_calls(self, listeners: tuple[StatusListener, ...]) -> None:
        self._update_calls = listeners
        self._update_one = listeners[0] if len(listeners) == 1 else None

    def _set_event_calls(self, listeners: tuple[EventListener, ...]) -> None:
        self._event_calls = listeners
        self._forget_key_if_unheard()

    def _set_event_refs(self, refs: tuple[weakref.ref[EventStream], ...]) -> None:
        self._event_refs = refs
        self._forget_key_if_unheard()

    def _forget_key_if_unheard(self) -> None:
        if not self._event_refs and not self._event_calls:
            # Nobody listens: forget the key so that the next listener compares the status
            # before its first frame with that frame.
            self._event_key = None

    def _subscribe(self, subscription: _Sub, registry: Subscribers[_Sub]) -> _Sub:
        if self.closed:
            subscription.close()
        else:
            registry.add(subscription)
        return subscription

    def _closed_error(self) -> ConnectionLost:
        """What a closed store fails with: the link's drop (its reason), else "closed"."""
        lost = self._link_error
        return lost if isinstance(lost, ConnectionLost) else ConnectionLost("the store is closed")

    def _raise_if_unusable(self) -> None:
        if self.closed:
            raise self._closed_error()
        if self._link_error is not None:
            raise self._link_error

    def _check_waiters(self, status: GalileoStatus) -> None:
        waiters = self._waiters
        settled = False
        for waiter in waiters:
            future = waiter.future
            if future.done():
                settled = True
                continue
            try:
                matched = waiter.predicate(status)
            except Exception as exc:  # a broken predicate fails its own waiter only
                future.set_exception(exc)
                settled = True
                continue
            if matched:
                future.set_result(status)
                settled = True
        if settled:  # rebuilt only when a waiter finished, not on every frame
            self._waiters = [w for w in waiters if not w.future.done()]

    def _fail_all(self, exc: GalileoConnectionError) -> None:
        self._fail_waiters(exc)
        for watch in self._watches:
            watch.fail(exc)

    def _fail_waiters(self, exc: GalileoConnectionError) -> None:
        waiters, self._waiters = self._waiters, []
        for waiter in waiters:
            if not waiter.future.done():
                waiter.future.set_exception(exc)

    def _emit(self, event: Event) -> None:
        for stream in self._event_streams:
            stream.offer(event)
        if self._event_calls:
            self._event_listeners.call(event)
        if _log.isEnabledFor(logging.DEBUG):
            _log.debug("event %s", type(event).__name__)
