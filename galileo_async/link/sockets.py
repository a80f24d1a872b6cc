"""SocketTransport: a lean TCP transport for socket:// links, on the loop's reader callbacks.

asyncio's socket transport runs four Python calls per read before the protocol sees a
byte (its read callback, the buffered-read branch, ``get_buffer``, ``buffer_updated``),
each reading attributes of a transport object that, across a fleet, the CPU cache no
longer holds. This one registers one read callback per socket with the event loop
(``loop.add_reader``) that reads into the protocol's buffer and hands the count over:
0.9 µs less per read at 1000 robots (BENCHMARKS.md §4). Writes go to the socket at once;
what it does not take waits for the socket to be writable (``get_write_buffer_size``
tells how much). Loops without reader callbacks (Windows' proactor) get asyncio's
transport instead (:func:`open_socket`).
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import socket
from collections.abc import Callable
from typing import Any

__all__ = ["SocketTransport", "open_socket"]

_log = logging.getLogger(__name__)
_Again = (BlockingIOError, InterruptedError)


class SocketTransport(asyncio.Transport):
    """A connected, non-blocking TCP socket and its protocol, on one event loop.

    A protocol with a ``socket_reader(transport)`` method reads the socket itself: the
    callable it returns is the loop's read callback, and it reports what ends the
    connection to ``read_failed(exc)`` or ``read_eof()``. The others are fed as asyncio
    feeds them (``get_buffer``/``buffer_updated``, or ``data_received``).
    """

    __slots__ = (
        "_buffered", "_closing", "_fd", "_loop", "_lost", "_pending", "_protocol", "_reader",
        "_reading", "_sock", "recv_into",
    )  # fmt: skip

    def __init__(
        self,
        loop: asyncio.AbstractEventLoop,
        sock: socket.socket,
        protocol: asyncio.BaseProtocol,
    ) -> None:
        """Take connected ``sock`` for ``protocol``; NotImplementedError without add_reader."""
        super().__init__()
        self._loop = loop
        self._sock = sock
        self._fd = sock.fileno()
        self._protocol = protocol
        #: The socket's recv_into, for a protocol that reads the socket itself.
        self.recv_into = sock.recv_into
        self._buffered = isinstance(protocol, asyncio.BufferedProtocol)
        self._reader = self._reader_of(protocol)
        self._pending = bytearray()  # what the socket has not taken yet
        self._closing = False
        self._lost = False
        self._reading = False
        self._extra = {"socket": sock, "sockname": sock.getsockname(), "peername": None}
        with contextlib.suppress(OSError):  # the peer may already be gone
            self._extra["peername"] = sock.getpeername()
        if sock.family in (socket.AF_INET, socket.AF_INET6):
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)  # as asyncio does
        self.resume_reading()  # NotImplementedError on a loop without reader callbacks
        protocol.connection_made(self)

    def __repr__(self) -> str:
        state = "closed" if self._lost else "closing" if self._closing else "open"
        return f"<SocketTransport fd={self._fd} {state}>"

    # --- reading ---------------------------------------------------------------------

    def _read_ready(self) -> None:
        protocol = self._protocol
        try:
            if self._buffered:
                buffer = protocol.get_buffer(-1)  # type: ignore[attr-defined]
                nbytes = self.recv_into(buffer)
            else:
                data = self._sock.recv(65536)
                nbytes = len(data)
        except _Again:
            return
        except OSError as exc:
            self.read_failed(exc)
            return
        if not nbytes:
            self.read_eof()
        elif self._buffered:
            protocol.buffer_updated(nbytes)  # type: ignore[attr-defined]
        else:
            protocol.data_received(data)  # type: ignore[attr-defined]

    def _reader_of(self, protocol: asyncio.BaseProtocol) -> Callable[[], None]:
        socket_reader = getattr(protocol, "socket_reader", None)
        reader: Callable[[], None] = self._read_ready
        if socket_reader is not None:
            reader = socket_reader(self)
        return reader

    def read_failed(self, exc: OSError) -> None:
        """Reading failed: the connection is lost with ``exc``."""
        self._fatal(exc)

    def read_eof(self) -> None:
        """The peer closed its side: ``eof_received()``, then close unless it says keep."""
        self.pause_reading()
        if not self._protocol.eof_received():  # type: ignore[attr-defined]
            self.close()

    def is_reading(self) -> bool:
        """True while the loop reads the socket for the protocol."""
        return self._reading

    def pause_reading(self) -> None:
        """Stop reading until resume_reading()."""
        if self._reading:
            self._reading = False
            self._loop.remove_reader(self._fd)

    def resume_reading(self) -> None:
        """Read again (no-op while closing)."""
        if not self._reading and not self._closing:
            self._loop.add_reader(self._fd, self._reader)
            self._reading = True

    # --- writing ---------------------------------------------------------------------

    def write(self, data: bytes | bytearray | memoryview) -> None:
        """Send ``data`` now, or as soon as the socket takes it (never blocks)."""
        if not isinstance(data, (bytes, bytearray, memoryview)):
            raise TypeError(f"data must be bytes-like, got {type(data).__name__}")
        if self._closing or not data:
            return
        if self._pending:
            self._pending += data
            return
        try:
            sent = self._sock.send(data)
        except _Again:
            sent = 0
        except OSError as exc:
            self._fatal(exc)
            return
        if sent < len(data):
            self._pending += memoryview(data)[sent:]
            self._loop.add_writer(self._fd, self._write_ready)

    def _write_ready(self) -> None:
        try:
            sent = self._sock.send(self._pending)
        except _Again:
            return
        except OSError as exc:
            self._fatal(exc)
            return
        del self._pending[:sent]
        if not self._pending:
            self._loop.remove_writer(self._fd)
            if self._closing:
                self._finish(None)

    def get_write_buffer_size(self) -> int:
        """Bytes written but not yet taken by the socket."""
        return len(self._pending)

    def can_write_eof(self) -> bool:
        """False: a link never half-closes."""
        return False

    # --- closing ---------------------------------------------------------------------

    def is_closing(self) -> bool:
        """True once close() or abort() was called, or the connection was lost."""
        return self._closing

    def close(self) -> None:
        """Stop reading; close once what is pending is sent; connection_lost(None) then."""
        if self._closing:
            return
        self.pause_reading()
        self._closing = True
        if not self._pending:
            self._finish(None)

    def abort(self) -> None:
        """Close now, dropping what is pending; connection_lost(None) then."""
        self._force_close(None)

    def _fatal(self, exc: OSError) -> None:
        _log.debug("%r: %r", self, exc)
        self._force_close(exc)

    def _force_close(self, exc: Exception | None) -> None:
        if self._lost:
            return
        self.pause_reading()
        self._closing = True
        if self._pending:
            self._pending.clear()
            self._loop.remove_writer(self._fd)
        self._finish(exc)

    def _finish(self, exc: Exception | None) -> None:
        if self._lost:
            return
        self._lost = True
        self._loop.call_soon(self._call_connection_lost, exc)

    def _call_connection_lost(self, exc: Exception | None) -> None:
        try:
            self._protocol.connection_lost(exc)
        finally:
            self._sock.close()

    # --- the rest of the transport API ----------------------------------------------------

    def get_extra_info(self, name: str, default: Any = None) -> Any:
        """``socket``, ``sockname`` or ``peername``; ``default`` for anything else."""
        return self._extra.get(name, default)

    def get_protocol(self) -> asyncio.BaseProtocol:
        """The protocol this transport feeds."""
        return self._protocol

    def set_protocol(self, protocol: asyncio.BaseProtocol) -> None:
        """Feed ``protocol`` from now on."""
        reading = self._reading
        self.pause_reading()
        self._protocol = protocol
        self._buffered = isinstance(protocol, asyncio.BufferedProtocol)
        self._reader = self._reader_of(protocol)
        if reading:
            self.resume_reading()


async def open_socket(
    loop: asyncio.AbstractEventLoop,
    factory: Callable[[], asyncio.BaseProtocol],
    host: str,
    port: int,
) -> tuple[asyncio.BaseTransport, asyncio.BaseProtocol]:
    """Connect to ``host:port`` (each address in turn) and wrap the socket for ``factory()``.

    A SocketTransport where the loop has reader callbacks, else asyncio's own transport.
    """
    infos = await loop.getaddrinfo(host, port, type=socket.SOCK_STREAM)
    if not infos:
        raise OSError(f"getaddrinfo({host!r}) returned no address")
    errors: list[OSError] = []
    for family, kind, proto, _name, address in infos:
        sock = socket.socket(family, kind, proto)
        try:
            sock.setblocking(False)
            await loop.sock_connect(sock, address)
        except OSError as exc:
            sock.close()
            errors.append(exc)
            continue
        except BaseException:
            sock.close()
            raise
        break
    else:
        if len(errors) == 1:
            raise errors[0]
        raise OSError(f"every address failed: {'; '.join(map(str, errors))}")
    protocol = factory()
    try:
        return SocketTransport(loop, sock, protocol), protocol
    except NotImplementedError:  # a loop without reader callbacks
        return await loop.create_connection(lambda: protocol, sock=sock)
    except BaseException:
        sock.close()
        raise
