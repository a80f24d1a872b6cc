"""Waiter and the future helpers the store and its streams wait with (no I/O)."""

from __future__ import annotations

import asyncio
from collections.abc import Callable
from typing import Any

from ..models import GalileoStatus

__all__ = ["Waiter", "expire", "fail_with"]


class Waiter:
    """A wait_until() call: its predicate and the future the store resolves."""

    __slots__ = ("future", "predicate")

    def __init__(
        self, predicate: Callable[[GalileoStatus], bool], future: asyncio.Future[GalileoStatus]
    ) -> None:
        self.predicate = predicate
        self.future = future


def expire(future: asyncio.Future[Any]) -> None:
    """Fail ``future`` with TimeoutError unless it is done (a call_later callback)."""
    if not future.done():
        future.set_exception(TimeoutError())


def fail_with(
    future: asyncio.Future[Any], source: asyncio.Future[Any] | None
) -> Callable[[], None]:
    """Fail ``future``, unless done, once ``source`` fails, as it did; returns the undo."""
    if source is None:
        return lambda: None

    def fail(done: asyncio.Future[Any]) -> None:
        if not future.done() and not done.cancelled() and done.exception() is not None:
            future.set_exception(done.exception())  # type: ignore[arg-type]

    def undo() -> None:
        source.remove_done_callback(fail)

    source.add_done_callback(fail)
    return undo
