"""BaseLink: the link of the HTTP and ROS kinds until they become channels under Link.

One paced writer, reconnect with back-off, a stale-link watchdog and stats, for
subclasses with a synchronous ``_write``; ``capabilities`` is computed from their flags.
"""

from __future__ import annotations

import abc
import asyncio
import logging
from collections import deque
from collections.abc import Callable
from typing import ClassVar, TypeAlias

from ..errors import ConnectionLost, GalileoConnectionError
from ..models import GalileoStatus
from ..protocol import Command
from . import options as _options
from .channel import Capabilities
from .follow import LinkStateFollowers, LinkStateStream
from .link import Link
from .queue import CommandQueue, Pending
from .stats import LinkState, LinkStats, StatusSink, loop_clock
from .watchdog import StaleWatchdog

__all__ = ["AnyLink", "BaseLink"]

_log = logging.getLogger(__name__)


class BaseLink(CommandQueue, StaleWatchdog, abc.ABC):
    """Transport-independent half of a link; subclasses connect, write and disconnect."""

    # Slots: a fleet touches every link 30 times a second, and attributes kept inside the
    # object are one memory block less to fetch each time (BENCHMARKS.md §2).
    __slots__ = (
        "__weakref__", "_backoff", "_closed", "_closing", "_connected_at", "_followers",
        "_last_write", "_opened", "_queue", "_queue_ready", "_reconnect_task", "_room_waiters",
        "_supersedable", "_writer_task", "drain_timeout", "max_queued_commands",
        "min_command_interval", "reconnect", "reconnect_initial", "reconnect_max",
        "stale_reconnect", "stale_timeout", "stats", "store",
    )  # fmt: skip
    #: True when the link writes a Velocity (a Twist) itself; serial links write f/b and c/d.
    carries_velocity: ClassVar[bool] = False
    #: True when the link writes a PoseGoal itself (http://); others add a target and go to it.
    carries_pose_goals: ClassVar[bool] = False
    #: True when the link makes ApiCalls (http://, https://): the Robot then has ``http``.
    carries_api_calls: ClassVar[bool] = False

    def __init__(
        self,
        store: StatusSink,
        *,
        reconnect: bool = True,
        reconnect_initial: float = _options.DEFAULT_RECONNECT_INITIAL,
        reconnect_max: float = _options.DEFAULT_RECONNECT_MAX,
        stale_timeout: float | None = _options.DEFAULT_STALE_TIMEOUT,
        stale_reconnect: float | None = _options.DEFAULT_STALE_RECONNECT,
        min_command_interval: float = _options.DEFAULT_MIN_COMMAND_INTERVAL,
        drain_timeout: float = _options.DEFAULT_DRAIN_TIMEOUT,
        max_queued_commands: int = _options.DEFAULT_MAX_QUEUED_COMMANDS,
    ) -> None:
        _options.check_options(
            reconnect=reconnect,
            reconnect_initial=reconnect_initial,
            reconnect_max=reconnect_max,
            stale_timeout=stale_timeout,
            stale_reconnect=stale_reconnect,
            min_command_interval=min_command_interval,
            drain_timeout=drain_timeout,
            max_queued_commands=max_queued_commands,
        )
        self.store = store
        self.stats = LinkStats()
        self.reconnect = reconnect
        self.reconnect_initial = reconnect_initial
        self.reconnect_max = reconnect_max
        self.stale_timeout = stale_timeout
        self.stale_reconnect = stale_reconnect
        self.min_command_interval = min_command_interval
        self.drain_timeout = drain_timeout
        self.max_queued_commands = max_queued_commands
        self._queue: deque[Pending] = deque()
        self._room_waiters: deque[asyncio.Future[None]] = deque()
        self._supersedable: list[tuple[Pending, tuple[type[Command], ...]]] = []
        self._queue_ready = asyncio.Event()
        self._writer_task: asyncio.Task[None] | None = None
        self._reconnect_task: asyncio.Task[None] | None = None
        #: The loop timer of the next stale check, if one is armed.
        self._watchdog = None
        self._last_write: float | None = None
        self._connected_at = 0.0
        self._opened = False
        self._state = LinkState.CONNECTING
        self._error: GalileoConnectionError | None = None
        self._followers = LinkStateFollowers()
        #: The wait before the next reopen of this outage; None: the first is reconnect_initial.
        self._backoff: float | None = None
        self._closing = False
        self._closed = asyncio.Event()

    @property
    def capabilities(self) -> Capabilities:
        """What the link can do, from its class flags (as Link.capabilities)."""
        return Capabilities(
            velocity=self.carries_velocity,
            pose_goals=self.carries_pose_goals,
            rest_api=self.carries_api_calls,
        )

    @property
    def error(self) -> GalileoConnectionError | None:
        """Why the link is STALE or LOST (as Link.error); None otherwise."""
        return self._error

    @property
    def connected(self) -> bool:
        """True while the transport is up."""
        return self.stats.connected

    @property
    def state(self) -> LinkState:
        """Where the link is (LinkState); each change is reported once to the store."""
        return self._state

    def _set_state(self, state: LinkState) -> None:
        """The one place the link's state changes: kept, counted in stats, told to followers."""
        self._state = self.stats.state = state
        self._followers.publish(state)

    def add_state_listener(self, listener: Callable[[LinkState], None]) -> None:
        """Call ``listener(state)`` synchronously at each later change of ``state``."""
        self._followers.add_listener(listener)

    def remove_state_listener(self, listener: Callable[[LinkState], None]) -> None:
        """Stop calling ``listener`` (no-op if it is not one)."""
        self._followers.remove_listener(listener)

    def states(self) -> LinkStateStream:
        """Async iterator: the state now, then each change; it ends after CLOSED."""
        return self._followers.stream(self._state)

    async def wait_state(self, *states: LinkState, timeout: float | None = None) -> LinkState:
        """The first of ``states`` the link is in, now or later; ConnectionLost once closed."""
        return await self._followers.wait(self._state, states, timeout)

    @property
    def closed(self) -> bool:
        """True once close() has started."""
        return self._closing

    # --- subclass interface --------------------------------------------------------------

    @abc.abstractmethod
    async def _connect(self) -> None:
        """Open the transport; raise GalileoConnectionError on failure."""

    @abc.abstractmethod
    def _write(self, command: Command) -> None:
        """Hand one command's bytes to the transport (one write); raise ConnectionLost if down."""

    @abc.abstractmethod
    async def _disconnect(self) -> None:
        """Close the transport, if any, and release what the link owns (bounded)."""

    def map_target_count(self) -> int | None:
        """How many targets the robot's map has, when the link can tell (once open); else None."""
        return None

    def _current_transport(self) -> asyncio.WriteTransport | None:
        """The asyncio transport written to, if any (default: ``self._transport`` if it is one)."""
        transport = getattr(self, "_transport", None)
        return transport if isinstance(transport, asyncio.WriteTransport) else None

    def _abandon(self, reason: str) -> None:
        """Give up a silent connection now: abort the transport, then handle it as a drop."""
        transport = self._current_transport()
        if transport is not None:
            transport.abort()
        self._on_lost(ConnectionLost(reason))

    # --- public API ------------------------------------------------------------------------

    async def open(self) -> None:
        """Make the first connection; raise GalileoConnectionError if it fails."""
        if self._closing:
            raise GalileoConnectionError("the link is closed")
        if self._opened:
            return
        # One clock for every timer of the link: its loop's (a virtual one in tests).
        self.stats.clock = loop_clock()
        await self._connect()
        self._opened = True
        self._writer_task = asyncio.create_task(self._writer(), name=f"{self!r} writer")
        self._on_connected()

    async def close(self) -> None:
        """Stop every task and timer, close the transport and the store (idempotent, bounded)."""
        if self._closing:
            await self._closed.wait()
            return
        self._closing = True
        self._set_state(LinkState.CLOSED)
        try:
            self._cancel_watchdog()
            tasks = [t for t in (self._writer_task, self._reconnect_task) if t is not None]
            for task in tasks:
                task.cancel()
            if tasks:
                await asyncio.wait(tasks, timeout=_options.CLOSE_TIMEOUT)
            self._writer_task = self._reconnect_task = None
            self._fail_pending(ConnectionLost("the link is closed"))
            self.stats.transport_open = False
            try:
                await asyncio.wait_for(self._disconnect(), _options.CLOSE_TIMEOUT)
            except (asyncio.TimeoutError, GalileoConnectionError, OSError) as exc:
                _log.warning("closing the transport failed: %r", exc)
            self.store.close()
        finally:
            self._closed.set()

    # --- called by subclasses --------------------------------------------------------------

    def _on_status(self, status: GalileoStatus) -> None:
        """Count one valid status and hand it to the store (links without a decoder).

        StreamLink's protocol does the same per read, its decoder having counted already.
        """
        stats = self.stats
        stats.decoder.frames += 1
        stats.decoder.layout = status.layout
        # Only a timestamp per status: the watchdog re-arms itself from it (_check_stale).
        stats.last_frame_at = stats.clock()
        if self._state is not LinkState.UP:
            self._fresh_again()
        self.store.update(status)

    def _fresh_again(self) -> None:
        """The first valid frame after connecting, a stale spell or a lost connection."""
        previous = self._state
        if previous is LinkState.CLOSED:
            return
        self._set_state(LinkState.UP)
        self._error = None
        if previous is LinkState.CONNECTING:
            return  # the watchdog runs from the connection's start
        if previous is LinkState.STALE:
            _log.info("link fresh again")
        else:  # lost: frames, not a reopened port, end the outage
            self._backoff = None
            _log.info("status frames again: connection restored")
        self.store.link_changed(LinkState.UP, None)
        self._arm_watchdog(self._stale_deadline(self.stats.clock()))

    def _on_lost(self, exc: BaseException | None) -> None:
        """The transport dropped (EOF, close or error): fail waiters, then reconnect."""
        if self._closing or not self.stats.connected:
            return
        self.stats.transport_open = False
        self._cancel_watchdog()
        reason = f"connection lost: {exc}" if exc is not None else "connection closed by the peer"
        error = self._error = ConnectionLost(reason)
        if self._state is LinkState.LOST:  # a reopened port that never answered: same outage
            _log.info("%s (no status frame since the reopen)", reason)
        else:
            self._set_state(LinkState.LOST)
            _log.warning("%s", reason)
        self._fail_pending(error)
        self.store.link_changed(LinkState.LOST, error)  # the store reports an outage once
        if self.reconnect:
            self._reconnect_task = asyncio.get_running_loop().create_task(
                self._reconnect_loop(), name=f"{self!r} reconnect"
            )
        else:
            # Nothing will feed the store again: end its iterators instead of leaving them hanging.
            self.store.close()

    # --- internals -------------------------------------------------------------------------

    def _on_connected(self) -> None:
        self.stats.transport_open = True
        self._connected_at = self.stats.clock()
        # A lost link stays lost until a valid frame comes (_fresh_again): a port reopens
        # fine when the node behind it is dead.
        self._arm_watchdog(self._stale_deadline(self._connected_at))
        if self._queue:
            self._queue_ready.set()

    def _next_reconnect_delay(self) -> float:
        """The wait before the next reopen: doubling up to reconnect_max over one outage."""
        # Kept across reopens that stay silent (a dead node behind a port that opens);
        # the first valid frame resets it (_fresh_again).
        delay = self.reconnect_initial if self._backoff is None else self._backoff
        self._backoff = min(delay * 2, self.reconnect_max)
        return delay

    async def _reconnect_loop(self) -> None:
        try:
            while not self._closing:
                await asyncio.sleep(self._next_reconnect_delay())
                try:
                    await self._connect()
                except Exception as exc:  # any failure: back off and try again
                    _log.info("reconnect failed (%s); next try in %.2f s", exc, self._backoff)
                    continue
                self.stats.reconnects += 1
                _log.info("reopened; lost until a status frame comes")
                self._on_connected()
                return
        finally:
            if self._reconnect_task is asyncio.current_task():
                self._reconnect_task = None

    def _check_can_send(self) -> None:
        """Raise ConnectionLost unless the link can take a command now."""
        if self._closing:
            raise ConnectionLost("the link is closed")
        if not self.stats.connected:
            again = ", reconnecting" if self._reconnect_task is not None else ""
            raise ConnectionLost(f"not connected{again}")

    def _write_buffer_size(self) -> int:
        transport = self._current_transport()
        if transport is None:
            return 0
        try:
            return transport.get_write_buffer_size()
        except NotImplementedError:  # a transport that cannot tell gets no flow control
            return 0

    async def _writer(self) -> None:
        queue = self._queue
        stalled_since: float | None = None
        while True:
            if not queue or not self.stats.connected:
                stalled_since = None
                self._queue_ready.clear()
                await self._queue_ready.wait()
                continue
            command, future = queue[0]
            if future.done():  # its sender was cancelled before the write
                queue.popleft()
                self._make_room()
                continue
            now = self.stats.clock()
            if self._last_write is not None:
                wait = self._last_write + self.min_command_interval - now
                if wait > 0:
                    await asyncio.sleep(wait)
                    continue
            # A stalled transport flushes what it buffered back to back in one segment, and
            # the firmware loses commands written back to back (docs/protocol.md §2): write only
            # into an empty buffer.
            buffered = self._write_buffer_size()
            if buffered:
                if stalled_since is None:
                    stalled_since = now
                elif now - stalled_since >= self.drain_timeout:
                    stalled_since = None
                    self._fail_pending(
                        GalileoConnectionError(
                            f"not sent: the transport still holds {buffered} unsent bytes "
                            f"after {self.drain_timeout} s (the peer does not read)"
                        )
                    )
                    continue
                await asyncio.sleep(_options.DRAIN_POLL_INTERVAL)
                continue
            stalled_since = None
            queue.popleft()
            self._make_room()
            try:
                self._write(command)
            except GalileoConnectionError as exc:
                future.set_exception(exc)
                continue
            except Exception as exc:  # a broken transport must not kill the only writer
                _log.exception("writing %s failed", command)
                error = GalileoConnectionError(f"writing {command} failed: {exc!r}")
                error.__cause__ = exc
                future.set_exception(error)
                continue
            self._last_write = self.stats.clock()
            self.stats.commands_sent += 1
            future.set_result(True)


#: Any robot link while the http:// and ros:// kinds are still BaseLinks.
AnyLink: TypeAlias = "Link | BaseLink"
