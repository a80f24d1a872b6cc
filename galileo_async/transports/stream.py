"""StreamChannel: status bytes from an asyncio transport through protocol.StatusDecoder."""

from __future__ import annotations

import asyncio
import logging
import threading
import weakref
from collections.abc import Awaitable, Callable
from typing import Any, cast

from ..errors import ConnectionLost, GalileoConnectionError
from ..models import StatusLayout
from ..protocol import Command, DecoderStats, StatusDecoder, encode
from .channel import Capabilities, Channel, Feed, frames_log
from .connectors import Connector, translate_errors
from .options import CLOSE_TIMEOUT

__all__ = ["StreamChannel"]

_log = logging.getLogger(__name__)
_DEBUG = logging.DEBUG
#: Most bytes one socket read takes (the rest waits for the next loop turn); 46 v2 frames.
READ_SIZE = 4096

# One read buffer per event loop, shared by all its links. A loop runs one read callback at
# a time and the decoder has taken what it needs before buffer_updated returns, so a loop
# needs no more; its links then read into memory the cache holds, where a buffer per link
# would be cold again by the link's next frame, a thirtieth of a second and a fleet of
# reads later (BENCHMARKS.md §2). Per loop, not per process: loops in other threads read
# concurrently.
_read_buffers: weakref.WeakKeyDictionary[asyncio.AbstractEventLoop, tuple[bytearray, memoryview]]
_read_buffers = weakref.WeakKeyDictionary()
_read_buffers_lock = threading.Lock()


def _read_buffer(loop: asyncio.AbstractEventLoop) -> tuple[bytearray, memoryview]:
    """The read buffer of ``loop``'s links and a view of it (made on first use)."""
    with _read_buffers_lock:
        try:
            pair = _read_buffers.get(loop)
            if pair is None:
                buffer = bytearray(READ_SIZE)
                pair = _read_buffers[loop] = (buffer, memoryview(buffer))
        except TypeError:  # a loop that takes no weak reference: a buffer of its own
            buffer = bytearray(READ_SIZE)
            pair = (buffer, memoryview(buffer))
    return pair


class _StreamProtocol(asyncio.BufferedProtocol, asyncio.Protocol):
    """Forwards one transport's bytes and its loss to the channel that made it.

    Sockets read into their loop's read buffer (BufferedProtocol): a plain Protocol is
    handed a fresh bytes object per read, which asyncio allocates at 256 KiB and shrinks,
    and which glibc serves by mmap until its threshold adapts: up to 6 µs a read at 30 Hz
    per robot (BENCHMARKS.md §2). It is a Protocol too: serial ports, pipes and custom
    connectors call data_received.
    """

    __slots__ = (
        "_buffer", "_channel", "_decoder", "_feed", "_stats", "_view", "current", "lost"
    )  # fmt: skip

    def __init__(self, channel: StreamChannel, feed: Feed, loop: asyncio.AbstractEventLoop) -> None:
        self._channel = channel
        self._decoder = channel.decoder
        self._feed = feed
        self._stats = feed.stats
        #: False once the channel has replaced or dropped this protocol: late reads are ignored.
        self.current = True
        self.lost: asyncio.Future[None] = loop.create_future()
        self._buffer, self._view = _read_buffer(loop)

    def get_buffer(self, sizehint: int) -> memoryview:
        return self._view

    # buffer_updated (sockets) and data_received (serial ports, pipes, custom connectors)
    # are the link's hot path, each written out in full rather than behind one more call:
    # one of them runs per read, 30 times a second per robot (BENCHMARKS.md §2).

    def buffer_updated(self, nbytes: int) -> None:
        if not self.current:
            return  # a late callback from a transport already replaced or closed
        self._stats.bytes_received += nbytes
        buffer = self._buffer
        if frames_log.isEnabledFor(_DEBUG):
            frames_log.debug("rx %s", buffer[:nbytes].hex(" "))
        if self._channel.raw_listeners:
            self._channel.tell_raw(self._view[:nbytes].tobytes())
        # Read in place: the decoder copies whatever it holds back, never keeps the buffer.
        statuses = self._decoder.feed_from(buffer, nbytes)  # counts into the link's stats
        if statuses:
            # feed.received written out (one call fewer per read): stamp, then deliver.
            stats = self._stats
            stats.last_frame_at = stats.clock()
            deliver = self._feed.deliver
            for status in statuses:
                deliver(status)

    def data_received(self, data: bytes | bytearray) -> None:
        if not self.current:
            return
        self._stats.bytes_received += len(data)
        if frames_log.isEnabledFor(_DEBUG):
            frames_log.debug("rx %s", data.hex(" "))
        if self._channel.raw_listeners:
            self._channel.tell_raw(bytes(data))
        statuses = self._decoder.feed_from(data, len(data))
        if statuses:
            stats = self._stats
            stats.last_frame_at = stats.clock()
            deliver = self._feed.deliver
            for status in statuses:
                deliver(status)

    def eof_received(self) -> bool | None:
        return None  # let the transport close itself: EOF is a drop

    def connection_lost(self, exc: Exception | None) -> None:
        if not self.lost.done():
            self.lost.set_result(None)
        self._channel._on_transport_lost(self, exc)


class StreamChannel(Channel):
    """The channel of any byte transport: serial, TCP, pty or an in-memory pair."""

    __slots__ = (
        "_closers", "_connector", "_feed", "_protocol", "_transport", "decoder", "name",
        "raw_listeners", "simulator",
    )  # fmt: skip

    capabilities = Capabilities(byte_stream=True)

    def __init__(
        self,
        connector: Connector,
        *,
        layout: StatusLayout | str | None = None,
        name: str | None = None,
    ) -> None:
        self.name = name
        self.decoder = StatusDecoder(layout)
        #: The in-process simulator behind a ``sim://`` link, else None.
        self.simulator: Any = None
        self._connector = connector
        self._feed: Feed | None = None
        self._transport: asyncio.WriteTransport | None = None
        self._protocol: _StreamProtocol | None = None
        self._closers: list[Callable[[], Awaitable[None]]] = []
        #: Called with every read's bytes as they came off the transport (add_raw_listener).
        self.raw_listeners: list[Callable[[bytes], None]] = []

    def __repr__(self) -> str:
        return f"<StreamChannel {self.name or 'custom'}>"

    @property
    def decoder_stats(self) -> DecoderStats:
        """The decoder's counters."""
        return self.decoder.stats

    @property
    def transport(self) -> asyncio.WriteTransport | None:
        """The asyncio transport written to while open, else None."""
        return self._transport

    def map_target_count(self) -> int | None:
        """The in-process simulator's map size on ``sim://``; else None (serial cannot tell)."""
        return None if self.simulator is None else len(self.simulator.config.targets)

    def add_raw_listener(self, listener: Callable[[bytes], None]) -> bool:
        """Call ``listener(data)`` with every read's bytes, before they are decoded."""
        self.raw_listeners.append(listener)
        return True

    def remove_raw_listener(self, listener: Callable[[bytes], None]) -> None:
        """Stop calling ``listener`` (no-op if it is not one)."""
        if listener in self.raw_listeners:
            self.raw_listeners.remove(listener)

    def tell_raw(self, data: bytes) -> None:
        """Hand ``data`` to every raw listener; one that raises is logged, the others run."""
        for listener in list(self.raw_listeners):
            try:
                listener(data)
            except Exception:
                _log.exception("raw listener %r failed", listener)

    def add_closer(self, closer: Callable[[], Awaitable[None]]) -> None:
        """Await ``closer()`` when the channel closes (for resources the link owns)."""
        self._closers.append(closer)

    async def open(self, feed: Feed) -> None:
        """Open the transport through the connector; report to ``feed``."""
        loop = asyncio.get_running_loop()
        self._feed = feed
        protocol = _StreamProtocol(self, feed, loop)
        self.decoder.reset()
        # Current before the connector returns: bytes may arrive before it does.
        self._set_protocol(protocol)
        try:
            with translate_errors(f"cannot connect to {self.name or 'the device'}"):
                transport, _ = await self._connector(loop, lambda: protocol)
        except BaseException:
            if self._protocol is protocol:
                self._set_protocol(None)
            raise
        if protocol.lost.done() or self._protocol is not protocol:
            transport.close()
            raise GalileoConnectionError(
                f"{self.name or 'the device'}: the connection closed while it was being opened"
            )
        self._transport = cast(asyncio.WriteTransport, transport)

    async def write(self, command: Command) -> None:
        """Hand one command's bytes to the transport (one write)."""
        transport = self._transport
        if transport is None or transport.is_closing():
            raise ConnectionLost("not connected")
        data = encode(command)
        if frames_log.isEnabledFor(_DEBUG):
            frames_log.debug("tx %s %s", data.hex(" "), command)
        transport.write(data)

    def pending_bytes(self) -> int:
        """What the transport buffered unsent (0 if it cannot tell)."""
        transport = self._transport
        if transport is None:
            return 0
        try:
            return transport.get_write_buffer_size()
        except NotImplementedError:  # a transport that cannot tell gets no flow control
            return 0

    def abandon(self, reason: str) -> None:
        """Abort the transport; its late loss is not reported."""
        transport = self._transport
        self._transport = None
        self._set_protocol(None)
        if transport is not None:
            transport.abort()

    async def close(self) -> None:
        """Close the transport (bounded), then the closers."""
        transport, protocol = self._transport, self._protocol
        self._transport = None
        self._set_protocol(None)
        try:
            if transport is not None and protocol is not None:
                transport.close()
                try:
                    await asyncio.wait_for(asyncio.shield(protocol.lost), CLOSE_TIMEOUT / 2)
                except asyncio.TimeoutError:
                    _log.warning("transport did not close in time; aborting it")
                    transport.abort()
        finally:
            closers, self._closers = self._closers, []
            for closer in closers:
                try:
                    await closer()
                except Exception:
                    _log.exception("closing %r failed", closer)

    def _on_transport_lost(self, protocol: _StreamProtocol, exc: Exception | None) -> None:
        if protocol is not self._protocol:
            return
        self._transport = None
        self._set_protocol(None)
        if self._feed is not None:
            self._feed.lost(exc)

    def _set_protocol(self, protocol: _StreamProtocol | None) -> None:
        """Make ``protocol`` the current one; the one it replaces ignores late reads."""
        previous = self._protocol
        if previous is not None and previous is not protocol:
            previous.current = False
        self._protocol = protocol
