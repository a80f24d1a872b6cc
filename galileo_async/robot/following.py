"""The Robot's public ways to follow it: its link state, and listeners of statuses and events."""

from __future__ import annotations

from .._checks import check_timeout
from ..errors import InvalidArgument
from ..state.listeners import EventListener, StatusListener
from ..state.store import StatusStore
from ..transports import Link, LinkState
from ..transports.follow import LinkStateStream
from .operations import Operations
from .runtime import ROBOT_DEFAULT, RobotDefault, or_default

__all__ = ["Following"]


class Following:
    """Robot's link state and listeners (a mixin: the link, store and ops are the Robot's)."""

    _link: Link
    _store: StatusStore
    _ops: Operations
    wait_timeout: float | None

    @property
    def link_state(self) -> LinkState:
        """Where the link is now: CONNECTING, UP, STALE, LOST or CLOSED (the link keeps it)."""
        return self._link.state

    def link_states(self) -> LinkStateStream:
        """Async iterator of the link's state: the state now, then each change; ends after CLOSED.

        Every change is kept (an outage is UP → STALE → LOST → UP); leaving the loop, or
        cancelling the task in it, stops following.
        """
        self._ops.ensure_loop()
        return self._link.states()

    async def wait_link(
        self, *states: LinkState, timeout: float | RobotDefault | None = ROBOT_DEFAULT
    ) -> LinkState:
        """Return the first of ``states`` the link is in, now or later.

        Left out, ``timeout`` is the Robot's ``wait_timeout``; None: no limit. GalileoTimeout
        after it; ConnectionLost once the link closes (unless CLOSED is one of ``states``);
        InvalidArgument for no state or one that is not a LinkState.
        """
        if not states or not all(isinstance(state, LinkState) for state in states):
            raise InvalidArgument(f"wait_link takes one or more LinkState, got {states!r}")
        seconds = or_default(timeout, self.wait_timeout)
        check_timeout("timeout", seconds)
        self._ops.ensure_loop()
        return await self._link.wait_state(*states, timeout=seconds)

    def add_update_listener(self, listener: StatusListener) -> None:
        """Call ``listener(status)`` with every later status, synchronously (keep it cheap).

        Any number of listeners; a listener that raises is logged, the others still run.
        """
        self._store.add_update_listener(listener)

    def remove_update_listener(self, listener: StatusListener) -> None:
        """Stop calling ``listener`` (no-op if it is not one)."""
        self._store.remove_update_listener(listener)

    def add_event_listener(self, listener: EventListener) -> None:
        """Call ``listener(event)`` with every later event, synchronously (keep it cheap)."""
        self._store.add_event_listener(listener)

    def remove_event_listener(self, listener: EventListener) -> None:
        """Stop calling ``listener`` (no-op if it is not one)."""
        self._store.remove_event_listener(listener)
