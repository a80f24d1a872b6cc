"""Simulator: one virtual Galileo served in-process, over TCP, UDP and a pty."""

from __future__ import annotations

import asyncio
import contextlib
import itertools
import ssl
import weakref
from collections.abc import Awaitable, Callable
from types import TracebackType
from typing import TYPE_CHECKING, Any
from urllib.parse import urlsplit

from ..errors import InvalidArgument
from ..models import GalileoStatus, Pose
from ..protocol import Command
from .config import SimConfig, parse_sim_url
from .device import DeviceConnection, DeviceStats, SimDevice, Ticker
from .memory import create_transport_pair
from .replay import ReplayConnection, load_capture
from .robot_model import RobotModel
from .serve import PtyTransport
from .udp import UdpFace

if TYPE_CHECKING:
    from .http import HttpFace

__all__ = ["Connector", "SimState", "Simulator"]

#: ``async (loop, protocol_factory) -> (transport, protocol)``: how a stream link connects.
Connector = Callable[
    [asyncio.AbstractEventLoop, Callable[[], asyncio.Protocol]],
    Awaitable[tuple[asyncio.BaseTransport, asyncio.Protocol]],
]

_CLOSE_TIMEOUT = 2.0
#: Simulators reachable by their ``url`` in this process.
_NAMED: weakref.WeakValueDictionary[str, Simulator] = weakref.WeakValueDictionary()
_IDS = itertools.count(1)


class SimState:
    """Read-only live view of the simulated robot (for tests, the CLI and dashboards)."""

    __slots__ = ("_device", "_model")

    def __init__(self, device: SimDevice) -> None:
        self._device = device
        self._model: RobotModel = device.model

    @property
    def status(self) -> GalileoStatus:
        """The status the next frame would carry (full v2 fields)."""
        return self._model.status()

    @property
    def time(self) -> float:
        """Simulated seconds since the robot started."""
        return self._model.time

    @property
    def time_stamp(self) -> int:
        """The frame counter of the last frame (0 before the first)."""
        return self._model.time_stamp

    @property
    def pose(self) -> Pose:
        """The true pose in the map frame, even when the status reports it unknown."""
        model = self._model
        return Pose(x=model.x, y=model.y, theta=model.theta)

    @property
    def targets(self) -> tuple[tuple[float, float], ...]:
        """Map targets followed by dynamic targets, by id."""
        return tuple(self._model.targets)

    @property
    def dock(self) -> tuple[float, float]:
        """The dock position."""
        return self._model.dock

    @property
    def patrol_dwell(self) -> float:
        """Seconds the patrol waits at each target."""
        return self._model.patrol_dwell

    @property
    def greeting(self) -> bool:
        """Greeting switched on."""
        return self._model.greeting

    @property
    def pending_commands(self) -> int:
        """Commands waiting for busy to end."""
        return self._model.pending

    @property
    def commands_handled(self) -> int:
        """Commands the robot has processed (queued ones once they ran)."""
        return self._model.commands_handled

    @property
    def shutdown(self) -> bool:
        """True after the host-shutdown command."""
        return self._model.shutdown

    @property
    def connections(self) -> int:
        """Hosts connected right now."""
        return len(self._device.connections)

    @property
    def stats(self) -> DeviceStats:
        """Frames, faults and commands counted by the device."""
        return self._device.stats


class Simulator:
    """A virtual Galileo on the device side of the protocol (see docs/simulator.md)."""

    def __init__(
        self, config: SimConfig | None = None, *, ticker: Ticker | None = None, **overrides: Any
    ) -> None:
        config = (config or SimConfig()).replace(**overrides)
        if ticker is not None and ticker.speed != config.speed:
            raise InvalidArgument(
                f"the shared ticker runs at speed {ticker.speed}, not {config.speed}"
            )
        self.config = config
        self._device = SimDevice(config, ticker or Ticker(config.speed), self._stop_serving)
        if config.robot is not None and config.replay is None:
            raise InvalidArgument("robot= picks the robot of a replay= recording: give replay=")
        self._capture = None if config.replay is None else load_capture(config.replay, config.robot)
        self._replays: list[ReplayConnection] = []
        self._servers: list[asyncio.Server] = []
        self._ptys: list[PtyTransport] = []
        self._udp: list[UdpFace] = []
        self._http: list[HttpFace] = []
        self._closed = False
        self._url: str | None = None
        #: While True, new in-process connections are refused (a link that is down).
        self.refuse_connections = False

    @classmethod
    def from_url(cls, url: str, *, ticker: Ticker | None = None, **overrides: Any) -> Simulator:
        """Build from ``sim://?speed=20&layout=v1&firmware=document&seed=1&targets=x,y;x,y``."""
        return cls(parse_sim_url(url).replace(**overrides), ticker=ticker)

    @property
    def url(self) -> str:
        """``sim://simulator-N``: connect() to this very simulator (in this process only)."""
        if self._url is None:
            self._url = f"sim://simulator-{next(_IDS)}"
            _NAMED[self._url] = self
        return self._url

    @classmethod
    def named(cls, url: str) -> Simulator | None:
        """The simulator whose ``url`` this is; None for a URL describing a new simulator."""
        parts = urlsplit(url)
        if not parts.netloc:
            return None
        simulator = _NAMED.get(f"sim://{parts.netloc}")
        if simulator is None:
            raise InvalidArgument(f"{url!r}: no simulator of that name in this process")
        if parts.query or parts.path not in ("", "/"):
            raise InvalidArgument(f"{url!r}: a named simulator takes no options")
        return simulator

    @property
    def muted(self) -> bool:
        """True while the robot sends no frame (it runs on; connections stay open)."""
        return self._device.muted

    @muted.setter
    def muted(self, value: bool) -> None:
        self._device.muted = bool(value)

    def on_command(self, listener: Callable[[Command], object]) -> None:
        """Call ``listener`` with every command the robot takes, in order, before it acts."""
        self._device.command_listeners.append(listener)

    def drop_connections(self) -> None:
        """Cut every in-process and TCP connection now (each host sees its link drop)."""
        for connection in list(self._device.connections):
            if connection.transport is not None:
                connection.transport.abort()

    @property
    def state(self) -> SimState:
        """Read-only live view of the robot."""
        return SimState(self._device)

    @property
    def model(self) -> RobotModel:
        """The underlying model (for fault injection such as ``abort_next_goal``)."""
        return self._device.model

    @property
    def accepting(self) -> bool:
        """False after close() or the host-shutdown command."""
        return not self._device.closed

    def start(self) -> None:
        """Start the robot's clock without a connection (needs a running loop)."""
        self._device.start()

    def connector(self) -> Connector:
        """A connector giving each call a fresh in-memory stream to this same robot."""

        async def connect(
            loop: asyncio.AbstractEventLoop, protocol_factory: Callable[[], asyncio.Protocol]
        ) -> tuple[asyncio.BaseTransport, asyncio.Protocol]:
            if self._device.closed:
                raise ConnectionRefusedError("the simulated robot is off")
            if self.refuse_connections:
                raise ConnectionRefusedError("the simulated link is down")
            protocol = protocol_factory()
            transport, _ = create_transport_pair(
                protocol, self._connection(), loop=loop, extra_a={"sim": self}
            )
            return transport, protocol

        return connect

    async def serve_tcp(self, host: str = "127.0.0.1", port: int = 0) -> asyncio.Server:
        """Listen on ``host:port`` (loopback by default); every client gets the status stream."""
        if self._device.closed:
            raise ConnectionRefusedError("the simulated robot is off")
        loop = asyncio.get_running_loop()
        server = await loop.create_server(self._connection, host, port)
        self._servers.append(server)
        if self._capture is None:
            self._device.start()
        return server

    async def serve_udp(self, host: str = "127.0.0.1", port: int = 0) -> UdpFace:
        """Serve the robot's UDP port on ``host:port`` (loopback default) to its last sender."""
        if self._device.closed:
            raise ConnectionRefusedError("the simulated robot is off")
        loop = asyncio.get_running_loop()
        face = UdpFace(self._device)
        await loop.create_datagram_endpoint(lambda: face, local_addr=(host, port))
        self._udp.append(face)
        self._device.listeners[face] = None
        self._device.start()
        return face

    async def serve_http(
        self,
        host: str = "127.0.0.1",
        port: int = 0,
        *,
        ws_port: int | None = None,
        token_check: bool = False,
        ssl_context: ssl.SSLContext | None = None,
    ) -> HttpFace:
        """Serve the vendor's HTTP API on ``host:port`` and its WebSocket on ``ws_port``.

        ``ws_port`` None: ``port + 1`` (0: any free port); ``ssl_context``: both over TLS.
        Needs aiohttp (the extra http).
        """
        if self._device.closed:
            raise ConnectionRefusedError("the simulated robot is off")
        from .http import HttpFace  # optional: aiohttp

        face = HttpFace(self._device, token_check=token_check, ssl_context=ssl_context)
        self._http.append(face)
        await face.start(host, port, 0 if port == 0 and ws_port is None else ws_port)
        self._device.start()
        return face

    def open_pty(self) -> str:
        """Serve over a new pseudo-terminal; returns the path a host opens as a serial port."""
        if self._device.closed:
            raise ConnectionRefusedError("the simulated robot is off")
        connection = self._connection(disconnectable=False)
        pty = PtyTransport(asyncio.get_running_loop(), connection)
        self._ptys.append(pty)
        return pty.path

    def _connection(self, *, disconnectable: bool = True) -> asyncio.Protocol:
        """The device end of a new connection: the robot, or the capture replayed."""
        if self._capture is None:
            return DeviceConnection(self._device, disconnectable=disconnectable)
        replay = ReplayConnection(self._capture, self.config.speed, f"replay {self.config.replay}")
        self._replays.append(replay)
        return replay

    def _stop_serving(self) -> None:
        for server in self._servers:
            server.close()
        for pty in self._ptys:
            pty.close()
        for face in self._udp:
            face.close()
        for http in self._http:
            http.close()

    async def close(self) -> None:
        """Stop the clock, drop every connection and listener; idempotent."""
        if self._closed:
            return
        self._closed = True
        self._device.stop()
        self._stop_serving()
        for replay in self._replays:
            replay.close()
            await replay.wait_closed()
        for server in self._servers:
            with contextlib.suppress(asyncio.TimeoutError):
                await asyncio.wait_for(server.wait_closed(), _CLOSE_TIMEOUT)
        self._servers.clear()
        self._ptys.clear()
        self._udp.clear()
        for http in self._http:
            await http.aclose()
        self._http.clear()
        await asyncio.sleep(0)  # let connection_lost callbacks run

    async def __aenter__(self) -> Simulator:
        return self

    async def __aexit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        await self.close()
