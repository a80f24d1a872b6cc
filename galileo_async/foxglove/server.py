"""FoxgloveServer: one Foxglove WebSocket server for any number of robots (docs/observability.md).

The SDK's server listens on a loopback port of its own; the public port is the relay's
(relay.py), which serves both subprotocol names. Closing the server sends no command to
any robot: it ends the service calls in flight, removes the listeners, stops the tick,
the relay and the SDK's server.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections.abc import Callable, Mapping, Sequence
from types import TracebackType
from typing import TYPE_CHECKING

import foxglove
from foxglove.websocket import Capability, ChannelView, Client, ServerListener, WebSocketServer

from ..errors import InvalidArgument
from ..robot.runtime import finish_shielded
from .channels import RobotChannels
from .relay import Relay
from .services import SERVICE_TIMEOUT, SERVICES, Calls, robot_services

if TYPE_CHECKING:
    from ..robot import Robot

__all__ = [
    "DEFAULT_HOST",
    "DEFAULT_PORT",
    "DEFAULT_RATE",
    "TICK",
    "FoxgloveServer",
    "serve_foxglove",
]

_log = logging.getLogger("galileo_async.foxglove")

DEFAULT_HOST = "127.0.0.1"
#: Foxglove's usual WebSocket port.
DEFAULT_PORT = 8765
#: Pose, transform and status messages per robot and second, at most.
DEFAULT_RATE = 10.0
#: Seconds between the link and scene messages of every robot.
TICK = 1.0
#: Messages queued per viewer before the oldest is dropped: a second of 1000 robots at the
#: default rate (the SDK's default, 1024, is 30 ms of them: a loop a little late drops).
BACKLOG = 32768

Targets = Sequence[tuple[int, float, float]]


class FoxgloveServer:
    """A Foxglove WebSocket server publishing robots added by add_robot (an async context)."""

    def __init__(
        self,
        *,
        host: str = DEFAULT_HOST,
        port: int = DEFAULT_PORT,
        rate: float = DEFAULT_RATE,
        name: str = "galileo_async",
        service_timeout: float = SERVICE_TIMEOUT,
    ) -> None:
        if not (isinstance(rate, (int, float)) and 0 < rate <= 100):
            raise InvalidArgument(f"rate must be 0 < rate <= 100 messages a second, got {rate!r}")
        if not (isinstance(port, int) and 0 <= port <= 65535):
            raise InvalidArgument(f"port must be 0..65535, got {port!r}")
        self.host, self.rate, self.name = host, float(rate), name
        self._port = port
        self._service_timeout = service_timeout
        self._context = foxglove.Context()
        self._robots: dict[str, RobotChannels] = {}
        self._sdk: WebSocketServer | None = None
        self._relay: Relay | None = None
        self._calls: Calls | None = None
        self._ticker: asyncio.Task[None] | None = None
        #: Map reads of removed robots, cancelled: close() waits for them.
        self._closing: set[asyncio.Task[None]] = set()
        self._close_task: asyncio.Task[None] | None = None

    @property
    def port(self) -> int:
        """The port viewers connect to (the one bound, when 0 was asked)."""
        if self._relay is None:
            raise RuntimeError("the Foxglove server is not started")
        return self._relay.port

    @property
    def url(self) -> str:
        """``ws://host:port``, what a viewer opens."""
        return f"ws://{self.host}:{self.port}"

    @property
    def robots(self) -> tuple[str, ...]:
        """The names of the robots published, in the order added."""
        return tuple(self._robots)

    async def start(self) -> None:
        """Listen on (host, port); OSError when the port is taken (nothing is left running)."""
        loop = asyncio.get_running_loop()
        self._close_task = None
        self._calls = Calls(loop)
        self._sdk = foxglove.start_server(
            name=self.name, host="127.0.0.1", port=0, context=self._context,
            capabilities=[Capability.Services], supported_encodings=["json"],
            message_backlog_size=BACKLOG, server_listener=_Subscriptions(loop, self._subscribed),
        )  # fmt: skip
        try:
            self._relay = Relay(self.host, self._port, self._sdk.port)
            await self._relay.start()
        except BaseException:
            self._relay = None
            self._sdk.stop()
            self._sdk = None
            raise
        self._ticker = asyncio.get_running_loop().create_task(self._tick(), name="foxglove tick")

    async def close(self) -> None:
        """Stop publishing and serving; no command is sent to any robot (idempotent).

        It completes whatever cancels the caller meanwhile (finish_shielded, bounded), and
        the caller's cancellation is raised once the port is free.
        """
        if self._close_task is None:
            self._close_task = asyncio.get_running_loop().create_task(
                self._close(), name="foxglove close"
            )
        await finish_shielded(self._close_task, "closing the Foxglove server")

    async def _close(self) -> None:
        try:
            if self._calls is not None:
                await self._calls.close()
            ticker, self._ticker = self._ticker, None
            if ticker is not None:
                ticker.cancel()
                await asyncio.wait({ticker})
            for name in list(self._robots):
                self.remove_robot(name)
            closing, self._closing = self._closing, set()
            if closing:
                await asyncio.wait(closing)
            relay, self._relay = self._relay, None
            if relay is not None:
                await relay.close()
        finally:
            sdk, self._sdk = self._sdk, None
            if sdk is not None:
                sdk.stop()

    async def __aenter__(self) -> FoxgloveServer:
        await self.start()
        return self

    async def __aexit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        await self.close()

    def add_robot(self, name: str, robot: Robot, *, targets: Targets = ()) -> None:
        """Publish ``robot`` as ``/name/...`` and serve its services; ``targets``: (id, x, y)."""
        if self._sdk is None or self._calls is None:
            raise RuntimeError("the Foxglove server is not started")
        if not name or "/" in name or name in self._robots:
            raise InvalidArgument(f"robot name must be new, non-empty and without '/': {name!r}")
        channels = RobotChannels(name, robot, self._context, rate=self.rate, targets=targets)
        try:
            self._sdk.add_services(
                robot_services(name, robot, self._calls, timeout=self._service_timeout)
            )
        except BaseException:
            channels.close()
            raise
        self._robots[name] = channels

    def remove_robot(self, name: str) -> None:
        """Stop publishing robot ``name`` and withdraw its services (KeyError if unknown)."""
        channels = self._robots.pop(name)
        reading = channels.close()
        if reading is not None and not reading.done():
            self._closing.add(reading)
            reading.add_done_callback(self._closing.discard)
        if self._sdk is not None:
            self._sdk.remove_services([f"/{name}/{service}" for service in SERVICES])

    def _subscribed(self, topic: str) -> None:
        """A viewer subscribed to ``topic`` (on the loop): a map topic has its map read."""
        channels = self._robots.get(topic.split("/")[1] if topic.count("/") == 2 else "")
        if channels is not None and channels.map is not None and topic in channels.map.topics:
            channels.map.wanted()

    async def _tick(self) -> None:
        while True:
            for channels in list(self._robots.values()):
                try:
                    channels.tick()
                except Exception:  # one robot's failure does not stop the others'
                    _log.exception("foxglove: publishing robot %s failed", channels.name)
            await asyncio.sleep(TICK)


class _Subscriptions(ServerListener):
    """The SDK's server listener: each subscription's topic handed to the loop."""

    def __init__(self, loop: asyncio.AbstractEventLoop, subscribed: Callable[[str], None]) -> None:
        self._loop, self._subscribed = loop, subscribed

    def on_subscribe(self, client: Client, channel: ChannelView) -> None:
        """Called on a thread of the SDK's."""
        with contextlib.suppress(RuntimeError):  # the loop closed: nobody to publish for
            self._loop.call_soon_threadsafe(self._subscribed, channel.topic)


async def serve_foxglove(
    robots: Mapping[str, Robot],
    *,
    host: str = DEFAULT_HOST,
    port: int = DEFAULT_PORT,
    rate: float = DEFAULT_RATE,
    targets: Mapping[str, Targets] | None = None,
    started: asyncio.Future[FoxgloveServer] | None = None,
) -> None:
    """Serve ``robots`` (name → Robot) to Foxglove until cancelled; closing sends no command.

    ``started``, if given, gets the running server (its port, when 0 was asked).
    """
    async with FoxgloveServer(host=host, port=port, rate=rate) as server:
        for name, robot in robots.items():
            server.add_robot(name, robot, targets=(targets or {}).get(name, ()))
        if started is not None and not started.done():
            started.set_result(server)
        await asyncio.Event().wait()  # until cancelled
