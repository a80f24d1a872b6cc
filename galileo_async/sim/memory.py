"""In-memory asyncio transports: two protocols talking through the event loop, no sockets."""

from __future__ import annotations

import asyncio
from collections.abc import Mapping
from typing import Any

__all__ = ["MemoryTransport", "create_transport_pair"]


class MemoryTransport(asyncio.Transport):
    """One end of an in-memory byte stream; writes reach the peer's data_received via call_soon."""

    def __init__(
        self,
        loop: asyncio.AbstractEventLoop,
        protocol: asyncio.Protocol,
        extra: Mapping[str, Any] | None = None,
    ) -> None:
        super().__init__(dict(extra or {}))
        self._loop = loop
        self._protocol = protocol
        self._peer: MemoryTransport | None = None
        self._closing = False
        self._lost = False
        self._closed_here = False  # closed by this end: stop delivering to our protocol
        self._reading = True
        self.bytes_written = 0

    # --- BaseTransport
    def get_protocol(self) -> asyncio.BaseProtocol:
        """The protocol this end delivers to."""
        return self._protocol

    def set_protocol(self, protocol: asyncio.BaseProtocol) -> None:
        """Deliver to another protocol from now on."""
        assert isinstance(protocol, asyncio.Protocol)
        self._protocol = protocol

    def is_closing(self) -> bool:
        """True once either end was closed."""
        return self._closing

    def close(self) -> None:
        """Close both ends: each protocol gets connection_lost(None) after pending data."""
        self._shutdown(None)

    def abort(self) -> None:
        """Close at once; the peer's protocol sees a ConnectionResetError."""
        self._shutdown(ConnectionResetError("the peer aborted the in-memory connection"))

    # --- ReadTransport
    def is_reading(self) -> bool:
        """Whether reading is (nominally) on; delivery is never held back."""
        return self._reading and not self._closing

    def pause_reading(self) -> None:
        """Record the pause; in-memory delivery does not stop."""
        self._reading = False

    def resume_reading(self) -> None:
        """Record the resume."""
        self._reading = True

    # --- WriteTransport
    def write(self, data: bytes | bytearray | memoryview) -> None:
        """Schedule ``data`` for the peer's data_received; ignored once closing."""
        if self._closing or not data:
            return
        peer = self._peer
        assert peer is not None, "transport not paired"
        self.bytes_written += len(data)
        self._loop.call_soon(peer._deliver, bytes(data))

    def writelines(self, list_of_data: Any) -> None:
        """Write the chunks joined as one."""
        self.write(b"".join(list_of_data))

    def can_write_eof(self) -> bool:
        """EOF is not supported: close instead."""
        return False

    def write_eof(self) -> None:
        """Not supported (like a serial port)."""
        raise NotImplementedError("in-memory transports do not support write_eof")

    def get_write_buffer_size(self) -> int:
        """Always 0: data is handed to the loop at once."""
        return 0

    def get_write_buffer_limits(self) -> tuple[int, int]:
        """No buffering, no limits."""
        return (0, 0)

    def set_write_buffer_limits(self, high: int | None = None, low: int | None = None) -> None:
        """No-op: nothing is buffered."""

    # --- internals
    def _deliver(self, data: bytes) -> None:
        # Data written before the peer closed still arrives, like a socket's FIN after data.
        if not self._lost and not self._closed_here:
            self._protocol.data_received(data)

    def _shutdown(self, peer_exc: Exception | None) -> None:
        if self._closing:
            return
        peer = self._peer
        self._closing = self._closed_here = True
        self._loop.call_soon(self._connection_lost, None)
        if peer is not None and not peer._closing:
            peer._closing = True
            self._loop.call_soon(peer._connection_lost, peer_exc)

    def _connection_lost(self, exc: Exception | None) -> None:
        if not self._lost:
            self._lost = True
            self._protocol.connection_lost(exc)


def create_transport_pair(
    protocol_a: asyncio.Protocol,
    protocol_b: asyncio.Protocol,
    *,
    loop: asyncio.AbstractEventLoop | None = None,
    extra_a: Mapping[str, Any] | None = None,
    extra_b: Mapping[str, Any] | None = None,
) -> tuple[MemoryTransport, MemoryTransport]:
    """Connect two protocols; both get connection_made before this returns (a first)."""
    loop = loop or asyncio.get_running_loop()
    transport_a = MemoryTransport(loop, protocol_a, {"peername": "memory", **(extra_a or {})})
    transport_b = MemoryTransport(loop, protocol_b, {"peername": "memory", **(extra_b or {})})
    transport_a._peer, transport_b._peer = transport_b, transport_a
    protocol_a.connection_made(transport_a)
    protocol_b.connection_made(transport_b)
    return transport_a, transport_b
