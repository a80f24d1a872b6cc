"""Connectors: coroutines that open a byte transport (serial, TCP) for StreamChannel."""

from __future__ import annotations

import asyncio
import contextlib
import errno
import importlib
import logging
import os
import re
import socket
from collections.abc import Awaitable, Callable, Iterator
from types import ModuleType
from typing import Any
from urllib.parse import urlsplit

from ..errors import GalileoConnectionError, GalileoError, InvalidArgument, PortBusy
from ..options import DEFAULT_BAUDRATE, DEFAULT_CONNECT_TIMEOUT
from .options import check_values
from .stats import clock_note, clocks

__all__ = [
    "DEFAULT_BAUDRATE",
    "DEFAULT_CONNECT_TIMEOUT",
    "Connector",
    "ProtocolFactory",
    "parse_host_port",
    "parse_socket_url",
    "serial_backend",
    "serial_connector",
    "set_keepalive",
    "socket_connector",
    "translate_errors",
]

_log = logging.getLogger(__name__)

#: TCP keepalive on socket:// connections: a peer whose host vanished sends no FIN; after
#: KEEPALIVE_IDLE s of silence, KEEPALIVE_COUNT unanswered probes KEEPALIVE_INTERVAL s apart
#: report it as a lost connection (about 11 s, instead of never).
KEEPALIVE_IDLE = 5
KEEPALIVE_INTERVAL = 2
KEEPALIVE_COUNT = 3

#: How opening a port that another holder has locked fails: pyserial's exclusive lock
#: (flock) gives EWOULDBLOCK, a port another program set TIOCEXCL on gives EBUSY.
_BUSY_ERRNOS = frozenset({errno.EAGAIN, errno.EWOULDBLOCK, errno.EBUSY})

ProtocolFactory = Callable[[], asyncio.Protocol]
#: Opens a transport and ties it to the protocol the factory makes.
Connector = Callable[
    [asyncio.AbstractEventLoop, ProtocolFactory],
    Awaitable[tuple[asyncio.BaseTransport, asyncio.Protocol]],
]


@contextlib.contextmanager
def translate_errors(what: str) -> Iterator[None]:
    """Turn transport-level exceptions into GalileoConnectionError (the link edge only)."""
    try:
        yield
    except GalileoError:
        raise
    # serial.SerialException subclasses OSError; asyncio.TimeoutError is separate before 3.11.
    except (OSError, EOFError, asyncio.TimeoutError) as exc:
        raise GalileoConnectionError(f"{what}: {_describe(exc)}") from exc


def _describe(exc: BaseException) -> str:
    """The message of ``exc``, or its kind when it has none (``str(TimeoutError())`` is empty)."""
    text = str(exc)
    if isinstance(exc, socket.gaierror):  # "[Errno -2] Name or service not known"
        return f"unknown host ({exc.strerror})"
    if isinstance(exc, (TimeoutError, asyncio.TimeoutError)):
        return text or "timed out"
    return text or type(exc).__name__


def serial_backend() -> ModuleType:
    """serial_asyncio_fast when installed (opens and closes off the loop), else serial_asyncio."""
    try:
        return importlib.import_module("serial_asyncio_fast")
    except ImportError:
        return importlib.import_module("serial_asyncio")


#: A port that looks like HOST:PORT, which a missing device likely was meant to be.
_HOST_PORT = re.compile(r"[\w.-]+:\d+|\[[0-9a-fA-F:.]+\]:\d+")


def serial_connector(
    port: str, *, baudrate: int = DEFAULT_BAUDRATE, **serial_options: Any
) -> Connector:
    """Connector for a serial device path or pyserial URL (8N1, no flow control).

    The port is opened exclusively (pyserial's ``exclusive``; ``exclusive=False`` in
    ``serial_options`` turns it off): a second opener, in this process or another, gets
    PortBusy instead of half of the byte stream.
    """
    check_values({"baudrate": baudrate})
    options = {"exclusive": True, **serial_options}

    async def connect(
        loop: asyncio.AbstractEventLoop, factory: ProtocolFactory
    ) -> tuple[asyncio.BaseTransport, asyncio.Protocol]:
        backend = serial_backend()
        with translate_errors(f"cannot open serial port {port}"):
            try:
                result: tuple[asyncio.BaseTransport, asyncio.Protocol]
                result = await backend.create_serial_connection(
                    loop, factory, port, baudrate=baudrate, **options
                )
            except ValueError as exc:  # pyserial: a bad setting or an unknown URL scheme
                raise InvalidArgument(f"serial port {port}: {exc}") from exc
            except OSError as exc:  # serial.SerialException is one
                if exc.errno in _BUSY_ERRNOS:
                    raise PortBusy(
                        f"serial port {port} is busy: another process or connection has it "
                        f"open ({_describe(exc)})",
                        port=port,
                    ) from exc
                if exc.errno:  # pyserial repeats "[Errno N] …" inside its own message
                    tcp = exc.errno == errno.ENOENT and _HOST_PORT.fullmatch(port)
                    hint = f" (for a TCP port write socket://{port})" if tcp else ""
                    raise GalileoConnectionError(
                        f"cannot open serial port {port}: {os.strerror(exc.errno)}{hint}"
                    ) from exc
                raise
        _log.debug("opened %s at %d baud with %s", port, baudrate, backend.__name__)
        return result

    return connect


def socket_connector(
    host: str,
    port: int,
    *,
    connect_timeout: float = DEFAULT_CONNECT_TIMEOUT,
    name: str | None = None,
) -> Connector:
    """Connector for a TCP byte stream (ser2net, a simulator); EOF counts as a drop.

    Its errors name ``name`` (the link's URL), else ``host:port``.
    """
    check_values({"connect_timeout": connect_timeout})
    what = f"cannot connect to {name or f'{host}:{port}'}"

    async def connect(
        loop: asyncio.AbstractEventLoop, factory: ProtocolFactory
    ) -> tuple[asyncio.BaseTransport, asyncio.Protocol]:
        began = clocks()
        with translate_errors(what):
            try:
                transport, protocol = await asyncio.wait_for(
                    loop.create_connection(factory, host, port), connect_timeout
                )
            except asyncio.TimeoutError:
                raise GalileoConnectionError(
                    f"{what}: no TCP connection within {connect_timeout} s (connect_timeout)"
                    f"{clock_note(began)}"
                ) from None
        set_keepalive(transport)
        return transport, protocol

    return connect


def set_keepalive(transport: asyncio.BaseTransport) -> None:
    """Turn on TCP keepalive with short timers (where the platform has them); best effort."""
    sock = transport.get_extra_info("socket")
    if sock is None:
        return
    options = [(socket.SOL_SOCKET, socket.SO_KEEPALIVE, 1)]
    for name, value in (
        ("TCP_KEEPIDLE", KEEPALIVE_IDLE),
        ("TCP_KEEPALIVE", KEEPALIVE_IDLE),  # macOS's name for the idle time
        ("TCP_KEEPINTVL", KEEPALIVE_INTERVAL),
        ("TCP_KEEPCNT", KEEPALIVE_COUNT),
    ):
        if hasattr(socket, name):
            options.append((socket.IPPROTO_TCP, getattr(socket, name), value))
    for level, option, value in options:
        with contextlib.suppress(OSError):  # the stale watchdog still catches a dead peer
            sock.setsockopt(level, option, value)


def parse_socket_url(url: str) -> tuple[str, int]:
    """(host, port) of ``socket://host:port`` (IPv6 hosts in brackets)."""
    return parse_host_port(url, "socket")


def parse_host_port(url: str, scheme: str, default_port: int | None = None) -> tuple[str, int]:
    """(host, port) of ``scheme://host:port`` (IPv6 hosts in brackets; port ``default_port``)."""
    parts = urlsplit(url)
    try:
        port = parts.port
    except ValueError as exc:
        raise InvalidArgument(f"bad port in {url!r}") from exc
    if port is None:
        port = default_port
    if parts.scheme != scheme or not parts.hostname or port is None:
        form = f"{scheme}://host" + (":port" if default_port is None else "[:port]")
        raise InvalidArgument(f"expected {form}, got {url!r}")
    return parts.hostname, port
