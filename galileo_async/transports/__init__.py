"""Transports: the one Link over small async channels, paced, supervised, counted.

``Link`` owns what every link shares (the queue, the one writer, reconnect, the stale timer,
the LinkState); a ``Channel`` connects one kind: ``StreamChannel`` (serial, ``socket://``,
``sim://``) and ``UdpChannel`` (``udp://``) here, ``ros.RosChannel`` and
``http.HttpChannel`` in their optional packages. ``urls`` is the one URL switch, also used
by the CLI.
"""

from __future__ import annotations

from .channel import Capabilities, Channel, Feed
from .connectors import (
    DEFAULT_BAUDRATE,
    DEFAULT_CONNECT_TIMEOUT,
    Connector,
    parse_socket_url,
    serial_connector,
    socket_connector,
    translate_errors,
)
from .follow import LinkStateStream
from .link import Link
from .options import (
    CLOSE_TIMEOUT,
    DEFAULT_DRAIN_TIMEOUT,
    DEFAULT_MAX_QUEUED_COMMANDS,
    DEFAULT_MIN_COMMAND_INTERVAL,
    DEFAULT_RECONNECT_INITIAL,
    DEFAULT_RECONNECT_MAX,
    DEFAULT_STALE_RECONNECT,
    DEFAULT_STALE_TIMEOUT,
    LINK_OPTIONS,
    STREAM_OPTIONS,
)
from .stats import LinkState, LinkStats, StatusSink, loop_clock
from .stream import StreamChannel
from .udp import UdpChannel
from .urls import URL_SCHEMES, byte_connector, check_link_options, link_kind, open_link, url_forms

__all__ = [
    "CLOSE_TIMEOUT",
    "DEFAULT_BAUDRATE",
    "DEFAULT_CONNECT_TIMEOUT",
    "DEFAULT_DRAIN_TIMEOUT",
    "DEFAULT_MAX_QUEUED_COMMANDS",
    "DEFAULT_MIN_COMMAND_INTERVAL",
    "DEFAULT_RECONNECT_INITIAL",
    "DEFAULT_RECONNECT_MAX",
    "DEFAULT_STALE_RECONNECT",
    "DEFAULT_STALE_TIMEOUT",
    "LINK_OPTIONS",
    "STREAM_OPTIONS",
    "URL_SCHEMES",
    "Capabilities",
    "Channel",
    "Connector",
    "Feed",
    "Link",
    "LinkState",
    "LinkStateStream",
    "LinkStats",
    "StatusSink",
    "StreamChannel",
    "UdpChannel",
    "byte_connector",
    "check_link_options",
    "link_kind",
    "loop_clock",
    "open_link",
    "parse_socket_url",
    "serial_connector",
    "socket_connector",
    "translate_errors",
    "url_forms",
]
