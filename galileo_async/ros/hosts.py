"""Peer host names: a robot's ROS nodes advertise a host name this host often cannot resolve."""

from __future__ import annotations

import asyncio
import logging
import socket
from collections.abc import Mapping
from urllib.parse import urlsplit, urlunsplit

from .._checks import host_key as _key
from .._checks import ip_literal as _ip
from .._checks import parse_hosts
from .xmlrpc import RosApiError

__all__ = ["RESOLVE_TIMEOUT", "PeerAddresses", "local_address_for", "parse_hosts"]

_log = logging.getLogger(__name__)

#: Longest a peer's host name may take to resolve before it counts as unresolvable.
RESOLVE_TIMEOUT = 2.0


class PeerAddresses:
    """Where to reach a host a peer advertises: the given map, the name if it resolves, else
    ``fallback`` (the master's address: on the robot, its nodes share the master's host)."""

    def __init__(self, hosts: Mapping[str, str], fallback: str) -> None:
        self._known = dict(hosts)  # lower-case name → address; a name's verdict is kept
        self.fallback = fallback

    async def address(self, host: str) -> str:
        """The address (or resolvable name) to connect to for ``host``."""
        key = _key(host)
        known = self._known.get(key)
        if known is not None:
            return known
        if _ip(host) is not None:
            return host
        loop = asyncio.get_running_loop()
        try:
            await asyncio.wait_for(
                loop.getaddrinfo(host, None, type=socket.SOCK_STREAM), RESOLVE_TIMEOUT
            )
        except (OSError, UnicodeError, asyncio.TimeoutError) as exc:
            _log.warning(
                "peer host %r does not resolve (%s): using the master's address %s "
                "(ros://…?hosts=%s=IP sets another)", host, exc, self.fallback, key,
            )  # fmt: skip
            self._known[key] = self.fallback
            return self.fallback
        self._known[key] = host
        return host

    async def uri(self, uri: str) -> str:
        """``uri`` with its host replaced by ``address(host)``."""
        parts = urlsplit(uri)
        if not parts.hostname:
            return uri
        address = await self.address(parts.hostname)
        if address == parts.hostname:
            return uri
        host = f"[{address}]" if ":" in address else address
        netloc = host if parts.port is None else f"{host}:{parts.port}"
        return urlunsplit(parts._replace(netloc=netloc))


async def local_address_for(master_uri: str) -> str:
    """The local IP address that routes to the master (what ROS_IP would be)."""
    host = urlsplit(master_uri).hostname or "127.0.0.1"
    port = urlsplit(master_uri).port or 11311
    loop = asyncio.get_running_loop()
    try:
        infos = await loop.getaddrinfo(host, port, type=socket.SOCK_DGRAM)
        family, _, _, _, address = infos[0]
        with socket.socket(family, socket.SOCK_DGRAM) as probe:
            probe.connect(address)  # UDP connect sends nothing; it only picks a route
            return str(probe.getsockname()[0])
    except (OSError, IndexError) as exc:
        raise RosApiError(f"cannot find a local address towards {host}: {exc}") from exc
