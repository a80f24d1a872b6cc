"""Link: the one link over any channel: queue, pacing, reconnect, stale watchdog, LinkState."""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Callable, Sequence
from typing import Any

from ..errors import ConnectionLost, GalileoConnectionError, LinkStale
from ..models import GalileoStatus
from ..protocol import Command
from . import options as _options
from .channel import Capabilities, Channel
from .commands import CommandQueue, PacedWriter
from .follow import LinkStateFollowers, LinkStateStream
from .stale import Watchdog
from .stats import LinkState, LinkStats, StatusSink, loop_clock

__all__ = ["Link"]

_log = logging.getLogger("galileo_async.transports.base")
_UP = LinkState.UP


class Link:
    """One robot link: a channel below, a store above, everything between them here.

    It is the channel's feed (channel.Feed): statuses and losses come in through
    ``received``, ``status`` and ``lost``.
    """

    # Slots: a fleet touches every link 30 times a second, and attributes kept inside the
    # object are one memory block less to fetch each time (BENCHMARKS.md §2).
    __slots__ = (
        "__weakref__", "_backoff", "_closed", "_closing", "_error", "_followers",
        "_opened", "_reconnect_task", "_state", "_update", "_writer_task", "channel",
        "deliver", "queue", "reconnect", "reconnect_initial", "reconnect_max", "stats",
        "store", "watchdog", "writer",
    )  # fmt: skip

    def __init__(
        self,
        channel: Channel,
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
        self.channel = channel
        self.store = store
        self._update = store.update
        self.stats = LinkStats(decoder=channel.decoder_stats)
        self.reconnect = reconnect
        self.reconnect_initial = reconnect_initial
        self.reconnect_max = reconnect_max
        self.queue = CommandQueue(max_queued_commands, self._check_can_send, self.stats)
        self._writer_task: asyncio.Task[None] | None = None
        self._reconnect_task: asyncio.Task[None] | None = None
        self.watchdog = Watchdog(
            self.stats,
            stale_timeout,
            stale_reconnect,
            watching=self._watching,
            fresh=self._fresh,
            stale=self._turn_stale,
            give_up=self._give_up,
        )
        self.writer = PacedWriter(
            self.queue, channel, self.stats, min_command_interval, drain_timeout
        )
        self._opened = False
        self._state = LinkState.CONNECTING
        #: Takes each valid status of a read (channel.Feed.deliver): the store's update
        #: while UP, else _deliver_fresh, which ends the spell first (_set_state swaps it).
        self.deliver: Callable[[GalileoStatus], None] = self._deliver_fresh
        #: The error that goes with the state (LOST, STALE), else None.
        self._error: GalileoConnectionError | None = None
        self._followers = LinkStateFollowers()
        #: The wait before the next reopen of this outage; None: the first is reconnect_initial.
        self._backoff: float | None = None
        self._closing = False
        self._closed = asyncio.Event()

    def __repr__(self) -> str:
        return f"<Link {self.channel.name or type(self.channel).__name__}>"

    # --- what the link is and can do ------------------------------------------------------

    @property
    def capabilities(self) -> Capabilities:
        """What the channel can do (velocity, pose goals, REST, bytes)."""
        return self.channel.capabilities

    @property
    def stale_timeout(self) -> float | None:
        """Seconds without a valid status before the link is STALE (None: never)."""
        return self.watchdog.stale_timeout

    @property
    def stale_reconnect(self) -> float | None:
        """Stale this many stale_timeouts: the connection is given up (None: never)."""
        return self.watchdog.stale_reconnect

    @property
    def max_queued_commands(self) -> int:
        """Most commands queued at once; send() waits for room beyond."""
        return self.queue.max_queued

    @property
    def connected(self) -> bool:
        """True while the transport is up."""
        return self.stats.connected

    @property
    def closed(self) -> bool:
        """True once close() has started."""
        return self._closing

    @property
    def state(self) -> LinkState:
        """Where the link is (LinkState); each change is reported once to the store."""
        return self._state

    @property
    def error(self) -> GalileoConnectionError | None:
        """Why the link is STALE or LOST (LinkStale, ConnectionLost); None otherwise."""
        return self._error

    def map_target_count(self) -> int | None:
        """How many targets the robot's map has, when the channel can tell (once open)."""
        return self.channel.map_target_count()

    # --- following the state -------------------------------------------------------------

    def _set_state(self, state: LinkState, error: GalileoConnectionError | None = None) -> None:
        """The one place the link's state changes: kept, counted in stats, told to followers."""
        self._state = self.stats.state = state
        # Swapped here, not tested per read: a byte channel calls deliver with no check.
        self.deliver = self._update if state is _UP else self._deliver_fresh
        if state is not LinkState.CLOSED:
            self._error = error
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

    # --- commands ------------------------------------------------------------------------

    def enqueue(
        self,
        command: Command,
        *,
        superseded_by: tuple[type[Command], ...] = (),
        written: asyncio.Future[bool] | None = None,
    ) -> asyncio.Future[bool]:
        """Queue ``command`` now, behind every earlier command and ahead of every later one.

        Synchronous, so a cancellation handler can queue a command before it awaits
        anything; it does not wait for room (max_queued_commands), so only callers that
        queue a bounded number of commands use it. The future is True once the command is
        written, False when it was dropped because a command of a type in
        ``superseded_by`` was queued after it first; cancelling it unqueues the command.
        Raises what the channel refuses the command with (InvalidArgument, NotSupported),
        or ConnectionLost while the link is closed or down. ``written``: use this future
        (see send) instead of a new one.
        """
        self.channel.accepts(command)
        return self.queue.enqueue(command, superseded_by=superseded_by, written=written).future

    async def send(self, command: Command, *, written: asyncio.Future[bool] | None = None) -> Any:
        """Queue one command for the paced writer (waiting while full); its answer once written.

        The answer is the channel's (None on byte channels). ``written``, if given, is the
        future the writer resolves: the caller may fail it (or cancel it) to withdraw the
        command; as long as that happens before its turn, synchronously, the command is
        never written and send raises that failure.
        """
        self.channel.accepts(command)
        return await self.queue.send(command, written=written)

    def _check_can_send(self) -> None:
        """Raise ConnectionLost unless the link can take a command now."""
        if self._closing:
            raise ConnectionLost("the link is closed")
        if not self.stats.connected:
            again = ", reconnecting" if self._reconnect_task is not None else ""
            raise ConnectionLost(f"not connected{again}")

    # --- open and close ------------------------------------------------------------------

    async def open(self) -> None:
        """Make the first connection; raise GalileoConnectionError if it fails."""
        if self._closing:
            raise GalileoConnectionError("the link is closed")
        if self._opened:
            return
        # One clock for every timer of the link: its loop's (a virtual one in tests).
        self.stats.clock = loop_clock()
        await self.channel.open(self)
        self._opened = True
        self._writer_task = asyncio.create_task(self.writer.run(), name=f"{self!r} writer")
        self._on_connected()

    async def close(self) -> None:
        """Stop every task and timer, close the channel and the store (idempotent, bounded)."""
        if self._closing:
            await self._closed.wait()
            return
        self._closing = True
        self._set_state(LinkState.CLOSED)
        try:
            self.watchdog.cancel()
            tasks = [t for t in (self._writer_task, self._reconnect_task) if t is not None]
            for task in tasks:
                task.cancel()
            if tasks:
                await asyncio.wait(tasks, timeout=_options.CLOSE_TIMEOUT)
            self._writer_task = self._reconnect_task = None
            self.queue.fail(ConnectionLost("the link is closed"))
            self.stats.transport_open = False
            try:
                await asyncio.wait_for(self.channel.close(), _options.CLOSE_TIMEOUT)
            except (asyncio.TimeoutError, GalileoConnectionError, OSError) as exc:
                _log.warning("closing the transport failed: %r", exc)
            self.store.close()
        finally:
            self._closed.set()

    # --- the channel's feed --------------------------------------------------------------

    def received(self, statuses: Sequence[GalileoStatus]) -> None:
        """Valid statuses of one read, counted by the channel's decoder already (hot path)."""
        stats = self.stats
        # Only a timestamp per read: the watchdog re-arms itself from it (_check_stale).
        stats.last_frame_at = stats.clock()
        deliver = self.deliver
        for status in statuses:
            deliver(status)

    def status(self, status: GalileoStatus) -> None:
        """Count one valid status and hand it to the store (channels without a decoder)."""
        stats = self.stats
        stats.decoder.frames += 1
        stats.decoder.layout = status.layout
        stats.last_frame_at = stats.clock()
        self.deliver(status)

    def _deliver_fresh(self, status: GalileoStatus) -> None:
        """``deliver`` while not UP: the first valid status ends the spell, then the store."""
        if self._state is not _UP:
            self._fresh_again()
        self._update(status)

    def lost(self, exc: BaseException | None) -> None:
        """The channel's connection dropped (EOF, close or error): fail waiters, reconnect."""
        if self._closing or not self.stats.transport_open:
            return
        self.stats.transport_open = False
        self.watchdog.cancel()
        reason = f"connection lost: {exc}" if exc is not None else "connection closed by the peer"
        error = ConnectionLost(reason)
        if self._state is LinkState.LOST:  # a reopened port that never answered: same outage
            _log.info("%s (no status frame since the reopen)", reason)
            self._error = error
        else:
            self._set_state(LinkState.LOST, error)
            _log.warning("%s", reason)
        self.queue.fail(error)
        self.store.link_changed(LinkState.LOST, error)  # the store reports an outage once
        if self.reconnect:
            self._reconnect_task = asyncio.get_running_loop().create_task(
                self._reconnect_loop(), name=f"{self!r} reconnect"
            )
        else:
            # Nothing will feed the store again: end its iterators instead of leaving them hanging.
            self.store.close()

    def _fresh_again(self) -> None:
        """The first valid frame after connecting, a stale spell or a lost connection."""
        previous = self._state
        if previous is LinkState.CLOSED:
            return
        self._set_state(LinkState.UP)
        if previous is LinkState.CONNECTING:
            return  # the watchdog runs from the connection's start
        if previous is LinkState.STALE:
            _log.info("link fresh again")
        else:  # lost: frames, not a reopened port, end the outage
            self._backoff = None
            _log.info("status frames again: connection restored")
        self.store.link_changed(LinkState.UP, None)
        self.watchdog.arm_from(self.stats.clock())

    # --- reconnect -----------------------------------------------------------------------

    def _on_connected(self) -> None:
        self.stats.transport_open = True
        # A lost link stays lost until a valid frame comes (_fresh_again): a port reopens
        # fine when the node behind it is dead.
        self.watchdog.start(self.stats.clock())
        if self.queue.entries:
            self.queue.ready.set()

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
                    await self.channel.open(self)
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

    # --- the stale watchdog's verdicts ----------------------------------------------------

    def _watching(self) -> bool:
        return not self._closing and self.stats.transport_open

    def _fresh(self) -> bool:
        return self._state is _UP or self._state is LinkState.CONNECTING

    def _turn_stale(self, silent: float) -> None:
        error = LinkStale(self.channel.stale_message(silent), silent_for=silent)
        self._set_state(LinkState.STALE, error)
        _log.warning("%s", error)
        self.store.link_changed(LinkState.STALE, error)
        self.channel.on_stale()

    def _give_up(self, silent: float) -> None:
        reason = f"no valid status frame for {silent:.2f} s: giving the connection up"
        _log.warning("%s", reason)
        self.channel.abandon(reason)
        self.lost(ConnectionLost(reason))
