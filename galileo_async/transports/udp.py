"""UdpChannel: the robot's UDP port 20001 (system_monitor) on asyncio's datagram transport.

The robot streams its status to the source address of the last datagram it received and
to nobody else (docs/protocol.md §7.4): the channel registers with ``cd eb d7 00`` (a
valid frame that does nothing) on every (re)connect and whenever it turns stale, and a
stale link says that another host may have taken the stream.
"""

from __future__ import annotations

import asyncio
import logging
from typing import Any
from urllib.parse import urlsplit

from ..errors import ConnectionLost, GalileoConnectionError, InvalidArgument
from ..protocol import HEADER, Command, DecoderStats, RawCommand, UdpStatusDecoder, encode
from .channel import Capabilities, Channel, Feed, frames_log
from .connectors import parse_host_port, translate_errors
from .options import CLOSE_TIMEOUT

__all__ = ["DEFAULT_UDP_PORT", "REGISTRATION", "UdpChannel", "check_datagram", "parse_udp_url"]

_log = logging.getLogger(__name__)

#: The robot's UDP command and status port (system_monitor config.py USERSOCKET_PORT).
DEFAULT_UDP_PORT = 20001
#: An empty frame: the robot parses it, does nothing, and streams to its sender from then on.
REGISTRATION = HEADER + b"\x00"
#: The shortest ``gi`` payload the robot's UDP service survives: a shorter one kills its
#: command thread until it restarts (docs/protocol.md §7.6).
_MIN_GI_PAYLOAD = 10


def parse_udp_url(url: str) -> tuple[str, int]:
    """(host, port) of ``udp://host[:port]`` (port 20001 by default, IPv6 hosts in brackets)."""
    parts = urlsplit(url)
    if parts.path not in ("", "/") or parts.query:
        raise InvalidArgument(f"udp:// takes no path or query, got {url!r}")
    return parse_host_port(url, "udp", DEFAULT_UDP_PORT)


def check_datagram(command: Command) -> None:
    """Raise InvalidArgument for a command that would stop the robot's UDP service."""
    data = command.data if isinstance(command, RawCommand) else b""
    if data[:2] == b"gi" and len(data) < _MIN_GI_PAYLOAD:
        raise InvalidArgument(
            f"a 'gi' payload shorter than {_MIN_GI_PAYLOAD} bytes stops the robot's UDP "
            f"service until it restarts; got {len(data)} bytes"
        )


class _DatagramProtocol(asyncio.DatagramProtocol):
    """Hands one endpoint's datagrams, errors and closing to the channel that made it."""

    __slots__ = ("_channel", "current", "lost")

    def __init__(self, channel: UdpChannel, loop: asyncio.AbstractEventLoop) -> None:
        self._channel = channel
        #: False once the channel replaced or dropped this endpoint: late datagrams are ignored.
        self.current = True
        self.lost: asyncio.Future[None] = loop.create_future()

    def datagram_received(self, data: bytes, addr: Any) -> None:
        if self.current:
            self._channel._on_datagram(data)

    def error_received(self, exc: Exception) -> None:
        if self.current:
            self._channel._on_error(exc)

    def connection_lost(self, exc: Exception | None) -> None:
        if not self.lost.done():
            self.lost.set_result(None)
        if self.current:
            self._channel._on_endpoint_lost(self, exc)


class UdpChannel(Channel):
    """The robot's UDP port: one command per datagram, status from the robot's port."""

    __slots__ = ("_feed", "_protocol", "_refused", "_transport", "decoder", "host", "name", "port")

    capabilities = Capabilities()

    def __init__(self, host: str, port: int = DEFAULT_UDP_PORT, *, name: str | None = None) -> None:
        self.host, self.port = host, port
        self.name = name or f"udp://{host}:{port}"
        self.decoder = UdpStatusDecoder()
        self._feed: Feed | None = None
        self._transport: asyncio.DatagramTransport | None = None
        self._protocol: _DatagramProtocol | None = None
        #: An ICMP error (port unreachable) came since the last valid frame.
        self._refused: Exception | None = None

    def __repr__(self) -> str:
        return f"<UdpChannel {self.name}>"

    @property
    def decoder_stats(self) -> DecoderStats:
        """The decoder's counters."""
        return self.decoder.stats

    def accepts(self, command: Command) -> None:
        """InvalidArgument for a command the robot's UDP service dies of (check_datagram)."""
        check_datagram(command)

    async def open(self, feed: Feed) -> None:
        """Open a connected datagram endpoint and register with the robot."""
        loop = asyncio.get_running_loop()
        self._feed = feed
        protocol = _DatagramProtocol(self, loop)
        self._drop_endpoint()
        self._protocol = protocol
        try:
            with translate_errors(f"cannot open {self.name}"):
                # Connected: the robot answers from its port 20001, and only its datagrams
                # reach this socket (docs/protocol.md §7.1).
                transport, _ = await loop.create_datagram_endpoint(
                    lambda: protocol, remote_addr=(self.host, self.port)
                )
        except BaseException:
            if self._protocol is protocol:
                self._protocol = None
            raise
        if self._protocol is not protocol:
            transport.close()
            raise GalileoConnectionError(f"{self.name}: closed while it was being opened")
        self._transport = transport
        self._refused = None
        self._register()

    def _register(self) -> None:
        """Send the registration datagram: the robot streams its status to us from now on."""
        transport = self._transport
        if transport is None or transport.is_closing():
            return
        if frames_log.isEnabledFor(logging.DEBUG):
            frames_log.debug("tx %s (registration)", REGISTRATION.hex(" "))
        transport.sendto(REGISTRATION)

    async def write(self, command: Command) -> None:
        """Send one command as one datagram."""
        transport = self._transport
        if transport is None or transport.is_closing():
            raise ConnectionLost("not connected")
        data = encode(command)  # one whole frame, never empty (docs/protocol.md §7.5, §7.6)
        if frames_log.isEnabledFor(logging.DEBUG):
            frames_log.debug("tx %s %s", data.hex(" "), command)
        transport.sendto(data)

    def pending_bytes(self) -> int:
        """What the datagram transport buffered unsent."""
        transport = self._transport
        # asyncio's datagram transports have it; the DatagramTransport interface does not.
        size = getattr(transport, "get_write_buffer_size", None)
        return 0 if size is None else int(size())

    def _on_datagram(self, data: bytes) -> None:
        feed = self._feed
        if feed is None:
            return
        feed.stats.bytes_received += len(data)
        if frames_log.isEnabledFor(logging.DEBUG):
            frames_log.debug("rx %s", data.hex(" "))
        statuses = self.decoder.feed(data)  # counts into the link's stats
        if statuses:
            self._refused = None
            feed.received(statuses)

    def _on_error(self, exc: Exception) -> None:
        # On a connected socket an ICMP port unreachable arrives as ConnectionRefusedError:
        # nothing listens on the robot's port (yet). The stale timer decides what it means.
        _log.debug("%s: %r", self.name, exc)
        self._refused = exc

    def stale_message(self, silent: float) -> str:
        """Silence on UDP: another host may have taken the stream, or the robot is away."""
        cause = (
            f"; the robot refused our datagrams ({self._refused})"
            if self._refused is not None
            else ""
        )
        return (
            f"no valid status frame for {silent:.2f} s from {self.name}: another host may "
            "have taken the UDP channel (the robot streams to the last sender only), or the "
            f"robot is unreachable{cause}"
        )

    def on_stale(self) -> None:
        """Take the stream back (or restart it after the robot's service restarted)."""
        self._register()

    def abandon(self, reason: str) -> None:
        """Drop the endpoint; the next open makes a new one."""
        self._drop_endpoint()

    def _on_endpoint_lost(self, protocol: _DatagramProtocol, exc: Exception | None) -> None:
        if protocol is not self._protocol:
            return
        self._transport = None
        self._protocol = None
        if self._feed is not None:
            self._feed.lost(exc)

    def _drop_endpoint(self) -> None:
        """Close the current endpoint, if any, without reporting it as lost."""
        transport, protocol = self._transport, self._protocol
        self._transport = self._protocol = None
        if protocol is not None:
            protocol.current = False
        if transport is not None:
            transport.abort()

    async def close(self) -> None:
        """Close the endpoint (bounded)."""
        transport, protocol = self._transport, self._protocol
        self._transport = self._protocol = None
        if protocol is not None:
            protocol.current = False
        if transport is not None and protocol is not None:
            transport.close()
            try:
                await asyncio.wait_for(asyncio.shield(protocol.lost), CLOSE_TIMEOUT / 2)
            except asyncio.TimeoutError:
                transport.abort()
