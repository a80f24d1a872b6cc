"""Status state without I/O: the store (latest status, waiters, link counts) and its streams."""

from __future__ import annotations

from .store import DEFAULT_EVENT_QUEUE, DEFAULT_WATCH_QUEUE, StatusStore
from .streams import BoundedQueue, EventStream, StatusSource, StatusStream, Subscribers, Watch

__all__ = [
    "DEFAULT_EVENT_QUEUE",
    "DEFAULT_WATCH_QUEUE",
    "BoundedQueue",
    "EventStream",
    "StatusSource",
    "StatusStore",
    "StatusStream",
    "Subscribers",
    "Watch",
]
