"""StreamLink: status bytes from an asyncio transport through protocol.StatusDecoder."""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Awaitable, Callable
from typing import Any, cast

from ..errors import ConnectionLost, GalileoConnectionError
from ..models import StatusLayout
from ..protocol import Command, StatusDecoder, encode
from .base import CLOSE_TIMEOUT, BaseLink, StatusSink, frames_log
from .connectors import Connector, translate_errors

__all__ = ["StreamLink"]

_log = logging.getLogger(__name__)
_DEBUG = logging.DEBUG


class _StreamProtocol(asyncio.Protocol):
    """Forwards one transport's bytes and its loss to the link that made it."""

    def __init__(self, link: StreamLink, loop: asyncio.AbstractEventLoop) -> None:
        self._link = link
        self.lost: asyncio.Future[None] = loop.create_future()

    def data_received(self, data: bytes) -> None:
        # The link's hot path, here rather than behind one more call: it runs per read.
        link = self._link
        if self is not link._protocol:
            return  # a late callback from a transport already replaced or closed
        stats = link.stats
        stats.bytes_received += len(data)
        if frames_log.isEnabledFor(_DEBUG):
            frames_log.debug("rx %s", data.hex(" "))
        statuses = link.decoder.feed(data)  # counts into stats itself
        if statuses:
            link._on_statuses(statuses)

    def eof_received(self) -> bool | None:
        return None  # let the transport close itself: EOF is a drop

    def connection_lost(self, exc: Exception | None) -> None:
        if not self.lost.done():
            self.lost.set_result(None)
        self._link._on_transport_lost(self, exc)


class StreamLink(BaseLink):
    """A link over any byte transport: serial, TCP, pty or an in-memory pair."""

    def __init__(
        self,
        store: StatusSink,
        connector: Connector,
        *,
        layout: StatusLayout | str | None = None,
        name: str | None = None,
        **base_options: Any,
    ) -> None:
        super().__init__(store, **base_options)
        self.name = name
        self.decoder = StatusDecoder(layout, stats=self.stats)
        #: The in-process simulator behind a ``sim://`` link, else None.
        self.simulator: Any = None
        self._connector = connector
        self._transport: asyncio.WriteTransport | None = None
        self._protocol: _StreamProtocol | None = None
        self._closers: list[Callable[[], Awaitable[None]]] = []

    def __repr__(self) -> str:
        return f"<StreamLink {self.name or 'custom'}>"

    def add_closer(self, closer: Callable[[], Awaitable[None]]) -> None:
        """Await ``closer()`` when the link closes (for resources the link owns)."""
        self._closers.append(closer)

    async def _connect(self) -> None:
        loop = asyncio.get_running_loop()
        protocol = _StreamProtocol(self, loop)
        self.decoder.reset()
        # Current before the connector returns: bytes may arrive before it does.
        self._protocol = protocol
        try:
            with translate_errors(f"cannot connect to {self.name or 'the device'}"):
                transport, _ = await self._connector(loop, lambda: protocol)
        except BaseException:
            if self._protocol is protocol:
                self._protocol = None
            raise
        if protocol.lost.done() or self._protocol is not protocol:
            transport.close()
            raise GalileoConnectionError("the connection closed while it was being opened")
        self._transport = cast(asyncio.WriteTransport, transport)

    def _write(self, command: Command) -> None:
        transport = self._transport
        if transport is None or transport.is_closing():
            raise ConnectionLost("not connected")
        data = encode(command)
        if frames_log.isEnabledFor(_DEBUG):
            frames_log.debug("tx %s %s", data.hex(" "), command)
        transport.write(data)

    async def _disconnect(self) -> None:
        transport, protocol = self._transport, self._protocol
        self._transport = self._protocol = None
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
        self._transport = self._protocol = None
        self._on_lost(exc)
