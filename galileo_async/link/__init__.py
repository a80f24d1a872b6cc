"""Links: bytes or ROS messages to and from the robot, paced, supervised and counted."""

from __future__ import annotations

import importlib
from typing import Any
from urllib.parse import urlsplit

from ..errors import GalileoConnectionError
from .base import BaseLink, LinkStats, StatusSink
from .connectors import (
    DEFAULT_BAUDRATE,
    DEFAULT_CONNECT_TIMEOUT,
    Connector,
    parse_socket_url,
    serial_connector,
    socket_connector,
    translate_errors,
)
from .options import (
    CLOSE_TIMEOUT,
    DEFAULT_DRAIN_TIMEOUT,
    DEFAULT_MAX_QUEUED_COMMANDS,
    DEFAULT_MIN_COMMAND_INTERVAL,
    DEFAULT_RECONNECT_INITIAL,
    DEFAULT_RECONNECT_MAX,
    DEFAULT_STALE_RECONNECT,
    DEFAULT_STALE_TIMEOUT,
)
from .stream import StreamLink

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
    "BaseLink",
    "Connector",
    "LinkStats",
    "StatusSink",
    "StreamLink",
    "open_link",
    "serial_connector",
    "socket_connector",
    "translate_errors",
]


def open_link(url: str, store: StatusSink, **options: Any) -> BaseLink:
    """A link (not yet opened) for a serial path, ``socket://``, ``sim://`` or ``ros://`` URL."""
    scheme = urlsplit(url).scheme.lower()
    if scheme == "ros":
        return _ros_link(url, store, options)
    baudrate = options.pop("baudrate", DEFAULT_BAUDRATE)
    serial_options = options.pop("serial_options", None) or {}
    connect_timeout = options.pop("connect_timeout", DEFAULT_CONNECT_TIMEOUT)
    if scheme == "socket":
        host, port = parse_socket_url(url)
        connector = socket_connector(host, port, connect_timeout=connect_timeout)
        return StreamLink(store, connector, name=url, **options)
    if scheme == "sim":
        simulator = importlib.import_module("galileo_async.sim").Simulator.from_url(url)
        link = StreamLink(store, simulator.connector(), name=url, **options)
        link.simulator = simulator
        link.add_closer(simulator.close)
        return link
    # Anything else is a device path or a pyserial URL (rfc2217://, loop://, …).
    connector = serial_connector(url, baudrate=baudrate, **serial_options)
    return StreamLink(store, connector, name=url, **options)


def _ros_link(url: str, store: StatusSink, options: dict[str, Any]) -> BaseLink:
    try:
        ros = importlib.import_module("galileo_async.link.ros")
        open_ros_link = ros.open_ros_link
    except (ImportError, AttributeError) as exc:
        raise GalileoConnectionError(
            f"ros:// links need the ROS support (pip install 'galileo-async[ros]'): {exc}"
        ) from exc
    link: BaseLink = open_ros_link(url, store, **options)
    return link
