"""Transports: the one Link over small async channels, paced, supervised, counted.

``Link`` owns what every link shares (the queue, the one writer, reconnect, the stale timer,
the LinkState); a ``Channel`` connects one kind: ``StreamChannel`` (serial, ``socket://``,
``sim://``) and ``UdpChannel`` (``udp://``) here, ``ros.RosChannel`` and
``http.HttpChannel`` in their optional packages. Which URL opens which channel is
``galileo_async.links``, the scheme table above every link kind.
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
    PORTABLE_OPTIONS,
    STREAM_OPTIONS,
)
from .stats import LinkState, LinkStats, StatusSink, clock_note, clocks, loop_clock
from .stream import StreamChannel
from .udp import UdpChannel

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
    "PORTABLE_OPTIONS",
    "STREAM_OPTIONS",
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
    "clock_note",
    "clocks",
    "loop_clock",
    "parse_socket_url",
    "serial_connector",
    "socket_connector",
    "translate_errors",
]
