"""Following a link's state: listeners called at each change, iterators and waits (no I/O)."""

from __future__ import annotations

import asyncio
import logging
import weakref
from collections import deque
from collections.abc import Callable, Iterable

from ..errors import ConnectionLost, GalileoTimeout
from .stats import LinkState

__all__ = ["LinkStateFollowers", "LinkStateStream"]

_log = logging.getLogger("galileo_async.transports.base")

LinkStateListener = Callable[[LinkState], None]


class LinkStateStream:
    """Async iterator of a link's states: the current one first, then each change, in order.

    Ends after CLOSED. Changes are few (one outage is three at most), so it keeps them all;
    a consumer that stops iterating may simply drop it (it is held weakly).
    """

    __slots__ = ("__weakref__", "_buffer", "_followers", "_wakeup", "closed")

    def __init__(self, followers: LinkStateFollowers, current: LinkState) -> None:
        self._followers = followers
        self._buffer: deque[LinkState] = deque((current,))
        self._wakeup: asyncio.Future[None] | None = None
        self.closed = False

    def _offer(self, state: LinkState) -> None:
        self._buffer.append(state)
        self._wake()

    def _wake(self) -> None:
        wakeup = self._wakeup
        if wakeup is not None and not wakeup.done():
            wakeup.set_result(None)

    def __aiter__(self) -> LinkStateStream:
        return self

    async def __anext__(self) -> LinkState:
        buffer = self._buffer
        while True:
            if buffer:
                state = buffer.popleft()
                if state is LinkState.CLOSED:
                    self.close()
                return state
            if self.closed:
                raise StopAsyncIteration
            # A cancelled wait leaves a done future behind: the next step makes a new one.
            self._wakeup = wakeup = asyncio.get_running_loop().create_future()
            try:
                await wakeup
            finally:
                self._wakeup = None

    def close(self) -> None:
        """Stop following (idempotent); states already buffered stay readable."""
        self._followers._streams.discard(self)
        self.closed = True
        self._wake()

    async def aclose(self) -> None:
        """Same as close(), for ``contextlib.aclosing``."""
        self.close()


class LinkStateFollowers:
    """Who follows one link's state; the link calls publish() at each change, once."""

    __slots__ = ("_listeners", "_streams")

    def __init__(self) -> None:
        self._listeners: tuple[LinkStateListener, ...] = ()
        self._streams: weakref.WeakSet[LinkStateStream] = weakref.WeakSet()

    def add_listener(self, listener: LinkStateListener) -> None:
        """Call ``listener(state)`` at each later change (synchronously; it must not block)."""
        self._listeners = (*self._listeners, listener)

    def remove_listener(self, listener: LinkStateListener) -> None:
        """Stop calling ``listener`` (no-op if it is not one)."""
        listeners = list(self._listeners)
        if listener in listeners:
            listeners.remove(listener)
            self._listeners = tuple(listeners)

    def stream(self, current: LinkState) -> LinkStateStream:
        """A new iterator that starts with ``current`` (the link's state now)."""
        stream = LinkStateStream(self, current)
        if current is LinkState.CLOSED:
            stream.closed = True
        else:
            self._streams.add(stream)
        return stream

    def publish(self, state: LinkState) -> None:
        """The link is now in ``state``: tell every listener and stream (never raises)."""
        for listener in self._listeners:
            try:
                listener(state)
            except Exception:  # one broken listener must not silence the others
                _log.exception("link state listener %r failed", listener)
        for stream in list(self._streams):
            stream._offer(state)

    async def wait(
        self, current: LinkState, states: Iterable[LinkState], timeout: float | None
    ) -> LinkState:
        """The first of ``states`` the link is in from now on (``current`` included).

        ConnectionLost once the link closes unless CLOSED is awaited; GalileoTimeout after
        ``timeout`` s (None: no limit).
        """
        wanted = frozenset(states)
        if current in wanted:
            return current
        if current is LinkState.CLOSED:
            raise ConnectionLost("the link is closed")
        future: asyncio.Future[LinkState] = asyncio.get_running_loop().create_future()

        def on_change(state: LinkState) -> None:
            if future.done():
                return
            if state in wanted:
                future.set_result(state)
            elif state is LinkState.CLOSED:
                future.set_exception(ConnectionLost("the link closed"))

        self.add_listener(on_change)
        try:
            return await asyncio.wait_for(future, timeout)
        except TimeoutError:
            names = " or ".join(sorted(state.value for state in wanted))
            raise GalileoTimeout(f"the link was not {names} within {timeout} s") from None
        finally:
            self.remove_listener(on_change)
