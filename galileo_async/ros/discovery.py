"""Find robots on the LAN: they broadcast JSON on UDP port 22002 at 10 Hz (docs/protocol.md §3)."""

from __future__ import annotations

import asyncio
import contextlib
import json
import socket
from dataclasses import dataclass
from typing import Any

from .._checks import check_int
from ..errors import GalileoConnectionError, InvalidArgument
from .channel import DEFAULT_MASTER_PORT

__all__ = ["DISCOVERY_PORT", "MAX_DATAGRAM", "DiscoveredRobot", "discover", "parse_announcement"]

#: The robots' broadcast port.
DISCOVERY_PORT = 22002
#: Announcements are a few dozen bytes; anything longer is not one.
MAX_DATAGRAM = 4096


@dataclass(frozen=True)
class DiscoveredRobot:
    """One robot that announced itself: its id, address, announced port, mac and version.

    ``port`` is the port the announcement names (the ROS master's 11311 on older firmware,
    the robot's HTTP service, 3546, on newer firmware); the ROS master is always at
    ``address``:``master_port``.
    """

    id: str
    address: str
    port: int
    mac: str | None = None
    version: str | None = None
    master_port: int = DEFAULT_MASTER_PORT

    @property
    def url(self) -> str:
        """The ``ros://`` URL of the robot's ROS master, to pass to ``galileo_async.connect``."""
        host = f"[{self.address}]" if ":" in self.address else self.address
        return f"ros://{host}:{self.master_port}"

    @property
    def urls(self) -> tuple[str, ...]:
        """Every URL the robot offers: ``http://`` when it announces its HTTP API, then ``url``.

        An announced port other than the master's is the HTTP API (3546 on 5.x firmware).
        """
        if self.port == self.master_port:
            return (self.url,)
        host = f"[{self.address}]" if ":" in self.address else self.address
        return (f"http://{host}:{self.port}", self.url)


def parse_announcement(data: bytes, address: str) -> DiscoveredRobot | None:
    """Decode one broadcast from ``address``; None when it is not a robot announcement."""
    if len(data) > MAX_DATAGRAM:
        return None
    try:
        payload: Any = json.loads(data.decode("utf-8"))
    except (UnicodeDecodeError, ValueError):
        return None
    if not isinstance(payload, dict) or "id" not in payload:
        return None
    port = payload.get("port", DEFAULT_MASTER_PORT)
    if isinstance(port, str) and port.isdigit():
        port = int(port)
    if not isinstance(port, int) or isinstance(port, bool) or not 0 < port < 65536:
        return None
    mac, version = payload.get("mac"), payload.get("version")
    return DiscoveredRobot(
        id=str(payload["id"]),
        address=address,
        port=port,
        mac=None if mac is None else str(mac),
        version=None if version is None else str(version),
    )


class _Listener(asyncio.DatagramProtocol):
    def __init__(self) -> None:
        self.found: dict[tuple[str, str], DiscoveredRobot] = {}

    def datagram_received(self, data: bytes, addr: tuple[str | Any, int]) -> None:
        robot = parse_announcement(data, str(addr[0]))
        if robot is not None:
            self.found[(robot.id, robot.address)] = robot

    def error_received(self, exc: Exception) -> None:  # ICMP noise: keep listening
        pass


def _socket(bind: str, port: int) -> socket.socket:
    family = socket.AF_INET6 if ":" in bind else socket.AF_INET
    sock = socket.socket(family, socket.SOCK_DGRAM)
    try:
        # Several listeners (processes, tests) may share the port.
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        if hasattr(socket, "SO_REUSEPORT"):
            with contextlib.suppress(OSError):
                sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEPORT, 1)
        sock.bind((bind, port))
        sock.setblocking(False)
    except BaseException:
        sock.close()
        raise
    return sock


async def discover(
    timeout: float = 1.0, *, bind: str = "", port: int = DISCOVERY_PORT
) -> list[DiscoveredRobot]:
    """Listen for ``timeout`` seconds; return each robot heard (latest announcement), by id."""
    if not timeout > 0:
        raise InvalidArgument(f"timeout must be positive, got {timeout!r}")
    check_int("port", port, 0, 65535)
    loop = asyncio.get_running_loop()
    try:
        sock = _socket(bind, port)
    except OSError as exc:
        raise GalileoConnectionError(f"cannot listen on UDP {bind or '*'}:{port}: {exc}") from exc
    transport, listener = await loop.create_datagram_endpoint(_Listener, sock=sock)
    try:
        await asyncio.sleep(timeout)
    finally:
        transport.close()
        # The transport closes its socket only on a later loop turn, which a cancelled
        # caller (an anyio cancel scope) may never give it: free the port now.
        sock.close()
    return sorted(listener.found.values(), key=lambda robot: (robot.id, robot.address))
