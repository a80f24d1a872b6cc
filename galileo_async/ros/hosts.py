"""Peer host names: a robot's ROS nodes advertise a host name this host often cannot resolve."""

from __future__ import annotations

import asyncio
import ipaddress
import logging
import re
import socket
from collections.abc import Mapping
from urllib.parse import urlsplit, urlunsplit

from ..errors import InvalidArgument
from .xmlrpc import RosApiError

__all__ = ["RESOLVE_TIMEOUT", "PeerAddresses", "local_address_for", "parse_hosts"]

_log = logging.getLogger(__name__)

#: Longest a peer's host name may take to resolve before it counts as unresolvable.
RESOLVE_TIMEOUT = 2.0
# RFC 1123 labels; underscores too, which robots' host names do use.
_LABEL = re.compile(r"[A-Za-z0-9_]([A-Za-z0-9_-]{0,61}[A-Za-z0-9_])?\Z")


def _is_host_name(name: str) -> bool:
    labels = name[:-1].split(".") if name.endswith(".") else name.split(".")
    return 0 < len(name) <= 253 and all(_LABEL.match(label) for label in labels)


def _key(name: str) -> str:
    return name.lower().rstrip(".")


def _ip(text: str) -> str | None:
    """``text`` as a normalised IP address literal, or None when it is not one."""
    try:
        return str(ipaddress.ip_address(text.strip("[]")))
    except ValueError:
        return None


def parse_hosts(hosts: str | Mapping[str, str]) -> dict[str, str]:
    """``name=ip,name2=ip2`` (or a mapping) → {lower-case name: ip}; InvalidArgument if bad."""
    if isinstance(hosts, str):
        pairs: list[tuple[str, str]] = []
        for entry in hosts.split(","):
            name, sep, address = entry.strip().partition("=")
            if not sep:
                raise InvalidArgument(f"hosts: expected name=ip, got {entry.strip()!r}")
            pairs.append((name.strip(), address.strip()))
    elif isinstance(hosts, Mapping):
        pairs = list(hosts.items())
    else:
        raise InvalidArgument(f"hosts must be 'name=ip,…' or a mapping, got {hosts!r}")
    parsed: dict[str, str] = {}
    for name, address in pairs:
        if not isinstance(name, str) or not _is_host_name(name):
            raise InvalidArgument(f"hosts: {name!r} is not a host name")
        ip = _ip(address) if isinstance(address, str) else None
        if ip is None:
            raise InvalidArgument(f"hosts: the address of {name} must be an IP, got {address!r}")
        if _key(name) in parsed:
            raise InvalidArgument(f"hosts: {name} is given twice")
        parsed[_key(name)] = ip
    return parsed


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
