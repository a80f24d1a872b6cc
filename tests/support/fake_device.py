"""Device-side fakes for link tests: a TCP loopback robot and an in-memory connector."""

from __future__ import annotations

import asyncio
import time
from collections.abc import Callable
from typing import Any

from galileo_async.models import GalileoStatus
from galileo_async.protocol import V2_DEFAULTS, Command, CommandDecoder, encode_status

__all__ = ["FakeDevice", "MemoryConnector", "RecordingTransport", "make_status", "status_frame"]


def make_status(**fields: Any) -> GalileoStatus:
    """A v2 status of a robot at 24 V: firmware defaults overridden by ``fields``."""
    return GalileoStatus(**{**V2_DEFAULTS, "power": 24.0, **fields})


def status_frame(time_stamp: int, **fields: Any) -> bytes:
    """Wire bytes of one v2 status frame."""
    return encode_status(make_status(time_stamp=time_stamp, **fields))


class _Changes:
    """Lets tests wait for a condition that the fake re-checks on every change."""

    def __init__(self) -> None:
        self._event = asyncio.Event()

    def notify(self) -> None:
        self._event.set()

    async def wait_for(self, predicate: Callable[[], bool], timeout: float = 2.0) -> None:
        async def until() -> None:
            while True:
                self._event.clear()
                if predicate():
                    return
                await self._event.wait()

        await asyncio.wait_for(until(), timeout)


class _DeviceProtocol(asyncio.Protocol):
    def __init__(self, device: FakeDevice) -> None:
        self.device = device
        self.transport: asyncio.Transport | None = None

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        assert isinstance(transport, asyncio.Transport)
        self.transport = transport
        self.device.clients.append(self)
        self.device.connections += 1
        self.device.accepted_at.append(time.monotonic())
        self.device.changes.notify()

    def data_received(self, data: bytes) -> None:
        self.device.writes.append((time.monotonic(), data))
        self.device.commands.extend(self.device.decoder.feed(data))
        self.device.changes.notify()

    def connection_lost(self, exc: Exception | None) -> None:
        if self in self.device.clients:
            self.device.clients.remove(self)
        self.device.changes.notify()


class FakeDevice:
    """A robot on 127.0.0.1: pushes status frames, records every write it receives."""

    def __init__(self) -> None:
        self.clients: list[_DeviceProtocol] = []
        self.connections = 0
        self.accepted_at: list[float] = []  # time.monotonic() of each accepted connection
        self.writes: list[tuple[float, bytes]] = []  # (time.monotonic(), one received chunk)
        self.commands: list[Command] = []
        self.decoder = CommandDecoder()
        self.changes = _Changes()
        self.time_stamp = 0
        self.port = 0
        self._server: asyncio.Server | None = None
        self._stream: asyncio.Task[None] | None = None

    @property
    def url(self) -> str:
        """``socket://`` URL of the device."""
        return f"socket://127.0.0.1:{self.port}"

    async def start(self) -> None:
        """Listen (on the previous port after a stop, else on a free one)."""
        loop = asyncio.get_running_loop()
        self._server = await loop.create_server(
            lambda: _DeviceProtocol(self), "127.0.0.1", self.port, reuse_address=True
        )
        self.port = self._server.sockets[0].getsockname()[1]

    def push(self, **fields: Any) -> None:
        """Send one status frame (next time_stamp) to every connected client."""
        self.time_stamp += 1
        self.push_raw(status_frame(self.time_stamp, **fields))

    def push_raw(self, data: bytes) -> None:
        """Send raw bytes to every connected client."""
        for client in self.clients:
            assert client.transport is not None
            client.transport.write(data)

    def start_stream(self, interval: float, **fields: Any) -> None:
        """Push a frame every ``interval`` seconds until stop_stream()."""

        async def stream() -> None:
            while True:
                self.push(**fields)
                await asyncio.sleep(interval)

        self._stream = asyncio.create_task(stream())

    async def stop_stream(self) -> None:
        """Stop the periodic frames."""
        if self._stream is not None:
            self._stream.cancel()
            await asyncio.gather(self._stream, return_exceptions=True)
            self._stream = None

    async def wait_for(self, predicate: Callable[[], bool], timeout: float = 2.0) -> None:
        """Wait until ``predicate()`` holds, re-checked on every connection or write."""
        await self.changes.wait_for(predicate, timeout)

    async def drop_clients(self) -> None:
        """Close every client connection from the device side."""
        for client in list(self.clients):
            assert client.transport is not None
            client.transport.close()
        await self.wait_for(lambda: not self.clients)

    async def stop(self) -> None:
        """Stop listening and drop every client."""
        await self.stop_stream()
        if self._server is not None:
            self._server.close()
            await self._server.wait_closed()
            self._server = None
        await self.drop_clients()


class RecordingTransport(asyncio.Transport):
    """In-memory transport: records writes with their times; close reports the loss."""

    def __init__(self, loop: asyncio.AbstractEventLoop, protocol: asyncio.Protocol) -> None:
        super().__init__()
        self.loop = loop
        self.protocol = protocol
        self.writes: list[tuple[float, bytes]] = []
        self.write_error: Exception | None = None  # raised by the next write when set
        self._closing = False

    def write(self, data: bytes | bytearray | memoryview) -> None:
        if self.write_error is not None:
            error, self.write_error = self.write_error, None
            raise error
        self.writes.append((time.monotonic(), bytes(data)))

    def is_closing(self) -> bool:
        return self._closing

    def close(self) -> None:
        self.lose(None)

    def abort(self) -> None:
        self.lose(None)

    def lose(self, exc: Exception | None) -> None:
        """Drop the connection; the protocol hears about it on the next loop pass."""
        if not self._closing:
            self._closing = True
            self.loop.call_soon(self.protocol.connection_lost, exc)


class MemoryConnector:
    """A Connector for StreamChannel: each connect makes a RecordingTransport, or fails."""

    def __init__(self) -> None:
        self.transports: list[RecordingTransport] = []
        self.attempts: list[float] = []
        self.failures = 0  # how many of the next connects raise OSError
        self._connected = asyncio.Event()

    async def __call__(
        self, loop: asyncio.AbstractEventLoop, factory: Callable[[], asyncio.Protocol]
    ) -> tuple[asyncio.BaseTransport, asyncio.Protocol]:
        self.attempts.append(time.monotonic())
        if self.failures:
            self.failures -= 1
            raise OSError("connection refused (fake)")
        protocol = factory()
        transport = RecordingTransport(loop, protocol)
        protocol.connection_made(transport)
        self.transports.append(transport)
        self._connected.set()
        return transport, protocol

    async def wait_connects(self, count: int, timeout: float = 2.0) -> None:
        """Wait until ``count`` connects have succeeded."""

        async def until() -> None:
            while len(self.transports) < count:
                self._connected.clear()
                await self._connected.wait()

        await asyncio.wait_for(until(), timeout)

    @property
    def transport(self) -> RecordingTransport:
        """The newest transport."""
        return self.transports[-1]

    def feed(self, data: bytes) -> None:
        """Bytes from the device to the link."""
        self.transport.protocol.data_received(data)
