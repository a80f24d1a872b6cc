"""Listeners: any number of synchronous callbacks, called in order with each item (no I/O)."""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import Generic, TypeVar

from ..events import Event
from ..models import GalileoStatus

__all__ = ["EventListener", "Listeners", "StatusListener"]

_log = logging.getLogger("galileo_async.state.store")

_T = TypeVar("_T")

StatusListener = Callable[[GalileoStatus], None]
EventListener = Callable[[Event], None]


class Listeners(Generic[_T]):
    """Callbacks of one kind of item; ``call(item)`` calls each in the order they were added.

    Each is called synchronously and must be cheap; one that raises is logged and the others
    still run. A callback added twice is called twice, and removed once per remove().
    """

    __slots__ = ("_kind", "_publish", "snapshot")

    def __init__(
        self, kind: str, publish: Callable[[tuple[Callable[[_T], None], ...]], None]
    ) -> None:
        """``kind`` names the item in the log; ``publish(snapshot)`` gets every new snapshot."""
        self._kind = kind
        self._publish = publish
        # An immutable snapshot: a listener that adds or removes one while called changes
        # the next call, not this one.
        self.snapshot: tuple[Callable[[_T], None], ...] = ()

    def add(self, listener: Callable[[_T], None]) -> None:
        """Call ``listener(item)`` with every later item."""
        self._set((*self.snapshot, listener))

    def remove(self, listener: Callable[[_T], None]) -> None:
        """Stop calling ``listener`` (its first addition; no-op if it is not one)."""
        for index, each in enumerate(self.snapshot):
            if each == listener:  # equal bound methods count as one
                self._set(self.snapshot[:index] + self.snapshot[index + 1 :])
                return

    def call(self, item: _T) -> None:
        """Call every listener with ``item``, in order; log any that raises."""
        for listener in self.snapshot:
            try:
                listener(item)
            except Exception:  # one broken listener must not stop the others
                _log.exception("%s listener %r failed", self._kind, listener)

    def _set(self, snapshot: tuple[Callable[[_T], None], ...]) -> None:
        self.snapshot = snapshot
        self._publish(snapshot)

    def __len__(self) -> int:
        return len(self.snapshot)
