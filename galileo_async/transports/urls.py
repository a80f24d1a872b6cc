"""The one URL switch: a serial path or a socket, udp, sim, ros or http[s] URL → its link."""

from __future__ import annotations

import pkgutil
from collections.abc import Collection, Mapping
from types import ModuleType
from typing import TYPE_CHECKING, Any
from urllib.parse import urlsplit

from .._checks import naming
from ..errors import GalileoConnectionError, InvalidArgument
from ..options import LINK_KINDS, check_options
from .connectors import (
    DEFAULT_BAUDRATE,
    DEFAULT_CONNECT_TIMEOUT,
    Connector,
    parse_socket_url,
    serial_connector,
    socket_connector,
)
from .link import Link
from .options import PORTABLE_OPTIONS
from .stats import StatusSink
from .stream import StreamChannel
from .udp import UdpChannel, parse_udp_url

if TYPE_CHECKING:
    from ..sim import Simulator

__all__ = [
    "LINK_SCHEMES",
    "URL_SCHEMES",
    "byte_connector",
    "check_link_options",
    "check_serial_url",
    "link_kind",
    "open_link",
    "serial_schemes",
    "url_forms",
]


#: The link kinds with a URL scheme of their own; anything else goes to the serial link.
LINK_SCHEMES = tuple(kind for kind in LINK_KINDS if kind != "serial")

#: Every URL scheme of a robot's port: its link kind (LINK_SCHEMES) and the address that
#: follows ``://``. Help texts and errors list the schemes from here (url_forms). A port
#: without one of them is a serial device: a path, or a URL pyserial opens (rfc2217://…).
URL_SCHEMES: dict[str, tuple[str, str]] = {
    "socket": ("socket", "host:port"),
    "udp": ("udp", "host[:port]"),
    "http": ("http", "host[:port]"),
    "https": ("http", "host[:port]"),
    "ros": ("ros", "host[:port]"),
    "sim": ("sim", "[?speed=…]"),
}


def link_kind(url: str) -> str:
    """``"ros"``, ``"socket"``, ``"udp"``, ``"sim"``, ``"http"`` or ``"serial"`` (a path …).

    ``https://`` URLs are of kind ``"http"``.
    """
    kind, _address = URL_SCHEMES.get(urlsplit(url).scheme.lower(), ("serial", ""))
    return kind


def url_forms() -> str:
    """Every form of a robot's port, for help texts: a serial device, then URL_SCHEMES."""
    forms = [f"{scheme}://{address}" for scheme, (_kind, address) in URL_SCHEMES.items()]
    return f"a serial device (/dev/ttyUSB0, COM3), {', '.join(forms[:-1])} or {forms[-1]}"


def serial_schemes() -> tuple[str, ...]:
    """The URL schemes pyserial opens itself (``rfc2217://``, ``loop://``, …)."""
    import serial.urlhandler

    modules = pkgutil.iter_modules(serial.urlhandler.__path__)
    names = (m.name.removeprefix("protocol_") for m in modules if m.name.startswith("protocol_"))
    return tuple(sorted(name for name in names if name not in URL_SCHEMES))


def check_serial_url(url: str) -> None:
    """InvalidArgument for a serial-link URL whose scheme no link knows (``foo://``)."""
    scheme, sep, rest = url.partition(":")
    # One letter is a Windows drive (C:\…), not a scheme.
    if not sep or len(scheme) < 2 or urlsplit(url).scheme.lower() != scheme.lower():
        return
    if scheme.lower() in serial_schemes():
        return
    known = ", ".join(f"{name}://" for name in (*URL_SCHEMES, *serial_schemes()))
    hint = f"; for a TCP port write socket://{url}" if rest.isdigit() else ""
    raise InvalidArgument(
        f"{url!r}: unknown URL scheme {scheme!r}; known: {known}, or a serial device path "
        f"(/dev/ttyUSB0, COM3){hint}"
    )


def check_link_options(
    url: str,
    options: Mapping[str, Any],
    *,
    also: Collection[str] = (),
    owners: Collection[str] = ("link",),
) -> None:
    """Raise InvalidArgument for a bad URL, an option its link does not take, or a bad value.

    Opens and builds nothing. ``owners``: whose options (galileo_async.options) are taken;
    ``also``: further option names the caller takes and checks itself.
    """
    kind = link_kind(url)
    if kind == "ros":
        _ros_module(url).check_ros_options(url, options, also=also, owners=owners)
        return
    if kind == "http":
        _http_module(url).check_http_options(url, options, also=also, owners=owners)
        return
    check_options(kind, options, owners=owners, also=also)
    if kind == "socket":
        parse_socket_url(url)
    elif kind == "udp":
        parse_udp_url(url)
    elif kind == "serial":
        check_serial_url(url)


def open_link(url: str, store: StatusSink, **options: Any) -> Link:
    """A link (not yet opened) for a serial path, ``socket://``, ``udp://``, ``sim://``, ``ros://``
    or ``http[s]://``."""
    if link_kind(url) == "http":  # its own checks: a password in the URL is never shown
        link: Link = _http_module(url).open_http_link(url, store, **options)
        return link
    with naming(url, repr(url)):
        check_link_options(url, options)
        return _open_link(url, store, options)


def byte_connector(
    url: str,
    *,
    baudrate: int = DEFAULT_BAUDRATE,
    serial_options: Mapping[str, Any] | None = None,
    connect_timeout: float = DEFAULT_CONNECT_TIMEOUT,
) -> tuple[Connector, Simulator | None]:
    """The connector of a byte-stream URL, and the simulator it runs for ``sim://``.

    InvalidArgument for ``ros://`` (messages, not bytes) or a bad socket URL; opens nothing.
    The caller closes the simulator.
    """
    kind = link_kind(url)
    if kind == "ros":
        raise InvalidArgument(f"{url!r}: a ros:// link carries ROS messages, not a byte stream")
    if kind == "udp":
        raise InvalidArgument(f"{url!r}: a udp:// link carries datagrams, not a byte stream")
    if kind == "http":
        raise InvalidArgument("an http:// link carries REST calls and JSON, not a byte stream")
    if kind == "socket":
        host, port = parse_socket_url(url)
        return socket_connector(host, port, connect_timeout=connect_timeout, name=url), None
    if kind == "sim":
        from ..sim import Simulator  # loaded only for sim:// URLs

        named = Simulator.named(url)  # one built in this process: its owner closes it
        if named is not None:
            return named.connector(), None
        simulator = Simulator.from_url(url)
        return simulator.connector(), simulator
    # Anything else is a device path or a pyserial URL (rfc2217://, loop://, …).
    check_serial_url(url)
    return serial_connector(url, baudrate=baudrate, **(serial_options or {})), None


def _open_link(url: str, store: StatusSink, options: dict[str, Any]) -> Link:
    kind = link_kind(url)
    if kind == "ros":
        return _ros_link(url, store, options)
    if kind == "udp":
        host, port = parse_udp_url(url)
        link_options = {k: v for k, v in options.items() if k not in PORTABLE_OPTIONS}
        return Link(UdpChannel(host, port, name=url), store, **link_options)
    connector, simulator = byte_connector(
        url,
        baudrate=options.pop("baudrate", DEFAULT_BAUDRATE),
        serial_options=options.pop("serial_options", None),
        connect_timeout=options.pop("connect_timeout", DEFAULT_CONNECT_TIMEOUT),
    )
    channel = StreamChannel(connector, layout=options.pop("layout", None), name=url)
    if simulator is not None:
        channel.simulator = simulator
        channel.add_closer(simulator.close)
    elif kind == "sim":
        from ..sim import Simulator

        channel.simulator = Simulator.named(url)
    return Link(channel, store, **options)


def _ros_module(url: str) -> ModuleType:
    try:
        # Optional, loaded only for ros:// URLs; spelled absolute so that the import asks
        # sys.modules (`from . import ros` would take a package attribute set earlier).
        import galileo_async.ros as ros
    except ImportError as exc:
        raise GalileoConnectionError(
            f"{url}: ros:// links need the ROS support (pip install 'galileo-async[ros]'): {exc}"
        ) from exc
    return ros


def _http_module(url: str) -> ModuleType:
    try:
        import galileo_async.http as http  # optional: aiohttp, the extra [http]
    except ImportError as exc:
        raise GalileoConnectionError(
            f"{urlsplit(url).scheme}:// links need aiohttp "
            f"(pip install 'galileo-async[http]'): {exc}"
        ) from exc
    return http


def _ros_link(url: str, store: StatusSink, options: dict[str, Any]) -> Link:
    link: Link = _ros_module(url).open_ros_link(url, store, **options)
    return link
