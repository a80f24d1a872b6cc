"""The scheme table: a robot's URL → its link kind, options and channel; extension by entry point.

One ``Scheme`` per link kind says which URL schemes it answers, the address form for help
texts, how to check a URL, which options of its own it takes, and how to build its channel
under the one Link (http:// and ros:// are loaded only for their URLs). A port
without a known scheme is a serial device. A distribution outside this package adds a
scheme through the entry point group ``galileo_async.channels``: each entry point names a
``Scheme``; they are loaded only when a URL has a scheme no built-in entry knows, or when
the schemes are listed for help texts; ``register`` adds one in this process.
"""

from __future__ import annotations

import dataclasses
import importlib.metadata
import logging
import pkgutil
from collections.abc import Callable, Collection, Mapping
from types import ModuleType
from typing import TYPE_CHECKING, Any
from urllib.parse import urlsplit

from ._checks import naming
from .errors import GalileoConnectionError, InvalidArgument
from .options import Option, check_options
from .transports import (
    DEFAULT_BAUDRATE,
    DEFAULT_CONNECT_TIMEOUT,
    LINK_OPTIONS,
    Channel,
    Connector,
    Link,
    StatusSink,
    StreamChannel,
    UdpChannel,
    parse_socket_url,
    serial_connector,
    socket_connector,
)
from .transports.udp import parse_udp_url

if TYPE_CHECKING:
    from .sim import Simulator

__all__ = [
    "ENTRY_POINT_GROUP",
    "SCHEMES",
    "URL_SCHEMES",
    "Scheme",
    "byte_connector",
    "check_link_options",
    "check_serial_url",
    "link_kind",
    "open_link",
    "register",
    "scheme_of",
    "serial_schemes",
    "url_forms",
    "url_schemes",
]

_log = logging.getLogger(__name__)

#: The entry point group through which another distribution adds a scheme (a Scheme).
ENTRY_POINT_GROUP = "galileo_async.channels"

#: (url, options) → the channel; ``options`` are the link's options that are not every
#: link's (LINK_OPTIONS): the scheme's own, and the portable ones, which it may ignore.
ChannelFactory = Callable[[str, dict[str, Any]], Channel]
_Names = Collection[str]
#: (url, options, also, owners) → None or InvalidArgument, for kinds that check their own.
OptionsCheck = Callable[[str, Mapping[str, Any], Collection[str], Collection[str]], None]
#: (url, baudrate, serial_options, connect_timeout) → a byte connector and the simulator
#: it runs (the caller closes it), for kinds that carry the serial protocol's bytes.
ConnectorFactory = Callable[
    [str, int, Mapping[str, Any], float], "tuple[Connector, Simulator | None]"
]


@dataclasses.dataclass(frozen=True)
class Scheme:
    """One entry of the scheme table: URL schemes, their link kind, options and channel."""

    #: The link kind (``Option.kinds`` names it; plugin kinds are their own).
    kind: str
    #: The URL schemes that open it, lower case (none for serial: every other port).
    schemes: tuple[str, ...]
    #: What follows ``://`` in help texts (``host[:port]``).
    address: str
    #: Builds the channel, from the URL and the options that are not every link's.
    channel: ChannelFactory | None = None
    #: Raises InvalidArgument for a URL of the scheme it cannot open (opens nothing);
    #: None: every URL of the scheme is taken as it is.
    check_url: Callable[[str], object] | None = None
    #: The kind's own options (each with ``name`` set); connect(), the CLI and fleet files
    #: take them for URLs of this kind only.
    options: tuple[Option, ...] = ()
    #: What it carries when it is no byte stream, for byte_connector's refusal.
    carries: str = ""
    #: Builds a byte connector (serial, socket://, sim://).
    connector: ConnectorFactory | None = None
    #: Checks URL and options itself, instead of ``check_url`` and ``options`` (kinds whose
    #: URL carries options or secrets, which its errors must not show: http, ros).
    check: OptionsCheck | None = None


# --- the built-in entries ---------------------------------------------------------------


def serial_schemes() -> tuple[str, ...]:
    """The URL schemes pyserial opens itself (``rfc2217://``, ``loop://``, …)."""
    import serial.urlhandler

    modules = pkgutil.iter_modules(serial.urlhandler.__path__)
    names = (m.name.removeprefix("protocol_") for m in modules if m.name.startswith("protocol_"))
    return tuple(sorted(name for name in names if name not in SCHEMES))


def check_serial_url(url: str) -> None:
    """InvalidArgument for a serial-link URL whose scheme no link knows (``foo://``)."""
    scheme, sep, rest = url.partition(":")
    # One letter is a Windows drive (C:\…), not a scheme.
    if not sep or len(scheme) < 2 or urlsplit(url).scheme.lower() != scheme.lower():
        return
    if scheme.lower() in serial_schemes():
        return
    known = ", ".join(f"{name}://" for name in (*url_schemes(), *serial_schemes()))
    hint = f"; for a TCP port write socket://{url}" if rest.isdigit() else ""
    raise InvalidArgument(
        f"{url!r}: unknown URL scheme {scheme!r}; known: {known}, or a serial device path "
        f"(/dev/ttyUSB0, COM3){hint}"
    )


def _serial_connector(
    url: str, baudrate: int, serial_options: Mapping[str, Any], timeout: float
) -> tuple[Connector, Simulator | None]:
    check_serial_url(url)  # a device path or a pyserial URL (rfc2217://, loop://, …)
    return serial_connector(url, baudrate=baudrate, **serial_options), None


def _socket_connector(
    url: str, baudrate: int, serial_options: Mapping[str, Any], timeout: float
) -> tuple[Connector, Simulator | None]:
    host, port = parse_socket_url(url)
    return socket_connector(host, port, connect_timeout=timeout, name=url), None


def _sim_connector(
    url: str, baudrate: int, serial_options: Mapping[str, Any], timeout: float
) -> tuple[Connector, Simulator | None]:
    from .sim import Simulator  # loaded only for sim:// URLs

    named = Simulator.named(url)  # one built in this process: its owner closes it
    if named is not None:
        return named.connector(), None
    simulator = Simulator.from_url(url)
    return simulator.connector(), simulator


def _stream_channel(url: str, options: dict[str, Any]) -> Channel:
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
    elif urlsplit(url).scheme.lower() == "sim":
        from .sim import Simulator

        channel.simulator = Simulator.named(url)
    return channel


def _udp_channel(url: str, options: dict[str, Any]) -> Channel:
    host, port = parse_udp_url(url)  # the portable options do not apply: ignored
    return UdpChannel(host, port, name=url)


def _http_module(url: str) -> ModuleType:
    try:
        import galileo_async.http as http  # optional: aiohttp, the extra [http]
    except ImportError as exc:
        raise GalileoConnectionError(
            f"{urlsplit(url).scheme}:// links need aiohttp "
            f"(pip install 'galileo-async[http]'): {exc}"
        ) from exc
    return http


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


def _http_channel(url: str, options: dict[str, Any]) -> Channel:
    channel: Channel = _http_module(url).http_channel(url, options)
    return channel


def _http_check(
    url: str, options: Mapping[str, Any], also: Collection[str], owners: Collection[str]
) -> None:
    _http_module(url).check_http_options(url, options, also=also, owners=owners)


def _ros_channel(url: str, options: dict[str, Any]) -> Channel:
    channel: Channel = _ros_module(url).ros_channel(url, options)
    return channel


def _ros_check(
    url: str, options: Mapping[str, Any], also: Collection[str], owners: Collection[str]
) -> None:
    _ros_module(url).check_ros_options(url, options, also=also, owners=owners)


#: The serial link: every port without a scheme of the table (a path, a pyserial URL).
SERIAL = Scheme(
    "serial", (), "", channel=_stream_channel, check_url=check_serial_url,
    connector=_serial_connector,
)  # fmt: skip
#: The built-in entries, in the order help texts list them.
BUILT_IN = (
    Scheme(
        "socket", ("socket",), "host:port", channel=_stream_channel,
        check_url=parse_socket_url, connector=_socket_connector,
    ),
    Scheme(
        "udp", ("udp",), "host[:port]", channel=_udp_channel, check_url=parse_udp_url,
        carries="datagrams",
    ),
    Scheme(
        "http", ("http", "https"), "host[:port]", channel=_http_channel, check=_http_check,
        carries="REST calls and JSON",
    ),
    Scheme(
        "ros", ("ros",), "host[:port]", channel=_ros_channel, check=_ros_check,
        carries="ROS messages",
    ),
    Scheme("sim", ("sim",), "[?speed=…]", channel=_stream_channel, connector=_sim_connector),
)  # fmt: skip
#: Every built-in URL scheme and its entry.
SCHEMES: dict[str, Scheme] = {scheme: entry for entry in BUILT_IN for scheme in entry.schemes}
#: Every built-in URL scheme of a robot's port: its link kind and the address after ``://``.
URL_SCHEMES: dict[str, tuple[str, str]] = {s: (e.kind, e.address) for s, e in SCHEMES.items()}

_plugins: dict[str, Scheme] | None = None


def _plugin_schemes() -> dict[str, Scheme]:
    """The entries other distributions add (ENTRY_POINT_GROUP), loaded on first use."""
    global _plugins
    if _plugins is None:
        found: dict[str, Scheme] = {}
        for point in importlib.metadata.entry_points(group=ENTRY_POINT_GROUP):
            try:
                entry = point.load()
            except Exception as exc:  # a broken plugin must not stop the built-in schemes
                _log.warning("the channel entry point %r failed to load: %r", point.name, exc)
                continue
            if not isinstance(entry, Scheme):
                _log.warning("the channel entry point %r is not a Scheme: %r", point.name, entry)
                continue
            for scheme in entry.schemes:
                if scheme in SCHEMES or scheme in found:
                    _log.warning("%s:// of %r is taken already; ignored", scheme, point.name)
                else:
                    found[scheme] = entry
        _plugins = found
    return _plugins


def register(entry: Scheme) -> None:
    """Add ``entry``'s schemes in this process, as an entry point does; InvalidArgument if taken."""
    plugins = _plugin_schemes()
    for scheme in entry.schemes:
        if scheme in SCHEMES or scheme in plugins or scheme != scheme.lower():
            raise InvalidArgument(f"{scheme}:// is taken already (or not lower case)")
    plugins.update((scheme, entry) for scheme in entry.schemes)


# --- the table's answers ----------------------------------------------------------------


def scheme_of(url: str) -> Scheme:
    """The entry of ``url``'s scheme (a plugin's, loaded then); SERIAL for anything else."""
    scheme = urlsplit(url).scheme.lower()
    entry = SCHEMES.get(scheme)
    if entry is not None:
        return entry
    if len(scheme) > 1:  # one letter is a Windows drive (C:\…)
        entry = _plugin_schemes().get(scheme)
        if entry is not None:
            return entry
    return SERIAL


def link_kind(url: str) -> str:
    """``"serial"``, ``"socket"``, ``"udp"``, ``"sim"``, ``"ros"``, ``"http"`` or a plugin's kind.

    ``https://`` URLs are of kind ``"http"``.
    """
    return scheme_of(url).kind


def url_schemes() -> dict[str, tuple[str, str]]:
    """URL_SCHEMES and the schemes other distributions add (loads their entry points)."""
    plugins = {s: (e.kind, e.address) for s, e in _plugin_schemes().items()}
    return {**URL_SCHEMES, **plugins}


def url_forms(*, plugins: bool = True) -> str:
    """Every form of a robot's port, for help texts: a serial device, then every scheme.

    ``plugins``: include the schemes other distributions add (loads their entry points).
    """
    schemes = url_schemes() if plugins else URL_SCHEMES
    forms = [f"{scheme}://{address}" for scheme, (_kind, address) in schemes.items()]
    return f"a serial device (/dev/ttyUSB0, COM3), {', '.join(forms[:-1])} or {forms[-1]}"


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
    _check(scheme_of(url), url, options, also, owners)


def _check(
    entry: Scheme, url: str, options: Mapping[str, Any], also: _Names, owners: _Names
) -> None:
    if entry.check is not None:
        entry.check(url, options, also, owners)
        return
    own = {option.name: option for option in entry.options}
    check_options(entry.kind, options, owners=owners, also=(*also, *own))
    for name, value in options.items():
        option = own.get(name)
        if option is not None and name not in also:
            option.check(value, entry.kind)
    if entry.check_url is not None:
        entry.check_url(url)


def open_link(url: str, store: StatusSink, **options: Any) -> Link:
    """A link (not yet opened) for a serial path or a URL of any scheme of the table."""
    entry = scheme_of(url)
    if entry.check is not None:  # its own checks: a password in the URL is never shown
        entry.check(url, options, (), ("link",))
        return _link(entry, url, store, options)
    with naming(url, repr(url)):
        _check(entry, url, options, (), ("link",))
        return _link(entry, url, store, options)


def _link(entry: Scheme, url: str, store: StatusSink, options: dict[str, Any]) -> Link:
    """The Link over ``entry``'s channel for ``url``; ``options`` checked already."""
    if entry.channel is None:
        raise InvalidArgument(f"{url!r}: the {entry.kind} entry builds no channel")
    link_options = {name: options.pop(name) for name in LINK_OPTIONS if name in options}
    return Link(entry.channel(url, options), store, **link_options)


def byte_connector(
    url: str,
    *,
    baudrate: int = DEFAULT_BAUDRATE,
    serial_options: Mapping[str, Any] | None = None,
    connect_timeout: float = DEFAULT_CONNECT_TIMEOUT,
) -> tuple[Connector, Simulator | None]:
    """The connector of a byte-stream URL, and the simulator it runs for ``sim://``.

    InvalidArgument for a URL whose link carries no bytes (``ros://``, ``udp://``,
    ``http://``) or a bad socket URL; opens nothing. The caller closes the simulator.
    """
    entry = scheme_of(url)
    if entry.connector is None:
        carries = entry.carries or "messages of its own"
        raise InvalidArgument(
            f"{url!r}: a {entry.kind}:// link carries {carries}, not a byte stream"
        )
    return entry.connector(url, baudrate, serial_options or {}, connect_timeout)
