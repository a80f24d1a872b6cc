"""The store's listeners: any number of callbacks per status and per event (no I/O)."""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import Any

from ..events import Event
from ..models import GalileoStatus

__all__ = ["EventListener", "Listeners", "StatusListener"]

_log = logging.getLogger("galileo_async.state.store")

StatusListener = Callable[[GalileoStatus], None]
EventListener = Callable[[Event], None]


def _without(listeners: tuple[Any, ...], listener: object) -> tuple[Any, ...]:
    """``listeners`` less the first ``listener`` (equal bound methods count as one)."""
    for index, each in enumerate(listeners):
        if each == listener:
            return listeners[:index] + listeners[index + 1 :]
    return listeners


class Listeners:
    """StatusStore's listener half: add/remove callbacks; the store calls them in order.

    Each listener is called synchronously, must be cheap, and is added once per call of
    add (adding it twice calls it twice). Tuples: the store's hot path iterates a snapshot.
    """

    __slots__ = ("_event_listeners", "_update_listeners", "_update_one")

    def __init__(self) -> None:
        self._update_listeners: tuple[StatusListener, ...] = ()
        # The only status listener, when there is exactly one (a fleet's): called without
        # a loop, per frame of every robot (BENCHMARKS.md §2).
        self._update_one: StatusListener | None = None
        self._event_listeners: tuple[EventListener, ...] = ()

    def add_update_listener(self, listener: StatusListener) -> None:
        """Call ``listener(status)`` with every later recorded status (placeholders are not)."""
        self._set_update_listeners((*self._update_listeners, listener))

    def remove_update_listener(self, listener: StatusListener) -> None:
        """Stop calling ``listener`` (no-op if it is not one)."""
        self._set_update_listeners(_without(self._update_listeners, listener))

    def _set_update_listeners(self, listeners: tuple[StatusListener, ...]) -> None:
        self._update_listeners = listeners
        self._update_one = listeners[0] if len(listeners) == 1 else None

    def add_event_listener(self, listener: EventListener) -> None:
        """Call ``listener(event)`` with every later event; events are derived while any listens."""
        self._event_listeners = (*self._event_listeners, listener)

    def remove_event_listener(self, listener: EventListener) -> None:
        """Stop calling ``listener`` (no-op if it is not one)."""
        self._event_listeners = _without(self._event_listeners, listener)
        self._listeners_changed()

    def _call_update_listeners(self, status: GalileoStatus) -> None:
        for listener in self._update_listeners:
            try:
                listener(status)
            except Exception:  # one broken listener must not stop the others
                _log.exception("status listener %r failed", listener)

    def _call_event_listeners(self, event: Event) -> None:
        for listener in self._event_listeners:
            try:
                listener(event)
            except Exception:  # one broken listener must not stop the others
                _log.exception("event listener %r failed", listener)

    def _listeners_changed(self) -> None:
        """An event listener went away (the store forgets its event key when none is left)."""
