"""RosChannel: the channel that drives a robot over its ROS 1 master (``ros://host:port``)."""

from __future__ import annotations

import dataclasses
import logging
import os
from collections.abc import Collection, Mapping
from typing import Any
from urllib.parse import parse_qs, urlsplit

from ..errors import ConnectionLost, GalileoConnectionError, InvalidArgument
from ..models import GalileoStatus
from ..options import OPTIONS, check_options, check_values
from ..protocol import Command, DecoderStats
from ..protocol.velocity import Velocity
from ..transports.channel import Capabilities, Channel, Feed
from ..transports.options import DEFAULT_STALE_RECONNECT, LINK_OPTIONS
from .hosts import local_address_for, parse_hosts
from .node import (
    DEFAULT_CONNECT_TIMEOUT,
    DEFAULT_MASTER_CHECK_INTERVAL,
    DEFAULT_RPC_TIMEOUT,
    NodeStats,
    RosNode,
    default_node_name,
)
from .xmlrpc import RosApiError

__all__ = [
    "DEFAULT_MASTER_PORT",
    "DEFAULT_STALE_RECONNECT",
    "GOAL_NUM_PARAM",
    "ROS_OPTIONS",
    "RosChannel",
    "check_ros_options",
    "parse_ros_url",
    "ros_channel",
]

_log = logging.getLogger(__name__)

DEFAULT_MASTER_PORT = 11311
#: The robot's target count, kept by its navigation node and read by the vendor's SDK.
GOAL_NUM_PARAM = "/galileo/goal_num"
#: Goal ids are one byte (docs/protocol.md §2.b).
_MAX_TARGETS = 255
_QUERY_OPTIONS: dict[str, Any] = {
    "host": str,
    "node_name": str,
    "connect_timeout": float,
    "hosts": parse_hosts,
}
# Serial-only options a generic caller may pass along; they mean nothing over ROS.
_IGNORED_OPTIONS = ("baudrate", "serial_options")
#: Options of a ros:// link on top of every link's (LINK_OPTIONS).
ROS_OPTIONS = tuple(
    name
    for name, option in OPTIONS.items()
    if option.owner == "link" and option.takes("ros") and name not in LINK_OPTIONS
)


def check_ros_options(
    url: str,
    options: Mapping[str, Any],
    *,
    also: Collection[str] = (),
    owners: Collection[str] = ("link",),
) -> None:
    """Raise InvalidArgument for a bad ros:// URL, an unknown option or a bad value; opens nothing.

    ``owners``: whose options (galileo_async.options) are taken; ``also``: further option
    names the caller takes and checks itself.
    """
    _, url_options = parse_ros_url(url)
    check_values(url_options, "ros")
    check_options("ros", options, owners=owners, also=also)


def parse_ros_url(url: str) -> tuple[str, dict[str, Any]]:
    """``ros://host[:port][?host=…&node_name=…&hosts=name=ip,…]`` → (master URI, options)."""
    parts = urlsplit(url)
    if parts.scheme.lower() != "ros" or not parts.hostname:
        raise InvalidArgument(f"not a ros://host[:port] URL: {url!r}")
    try:
        port = parts.port or DEFAULT_MASTER_PORT
    except ValueError as exc:
        raise InvalidArgument(f"bad port in {url!r}") from exc
    host = f"[{parts.hostname}]" if ":" in parts.hostname else parts.hostname
    options: dict[str, Any] = {}
    for key, values in parse_qs(parts.query).items():
        if key not in _QUERY_OPTIONS:
            raise InvalidArgument(f"unknown option {key!r} in {url!r}")
        try:
            options[key] = _QUERY_OPTIONS[key](values[-1])
        except ValueError as exc:  # InvalidArgument is one too
            raise InvalidArgument(f"bad value for {key} in {url!r}: {exc}") from exc
    return f"http://{host}:{port}/", options


class RosChannel(Channel):
    """Commands published on /galileo/cmds, statuses from /galileo/status (any version).

    A Velocity (drive()) is published as geometry_msgs/Twist on /cmd_vel.
    """

    capabilities = Capabilities(velocity=True)

    def __init__(
        self,
        master_uri: str,
        *,
        host: str | None = None,
        bind: str | None = None,
        node_name: str | None = None,
        connect_timeout: float = DEFAULT_CONNECT_TIMEOUT,
        rpc_timeout: float = DEFAULT_RPC_TIMEOUT,
        master_check_interval: float = DEFAULT_MASTER_CHECK_INTERVAL,
        hosts: str | Mapping[str, str] | None = None,
        name: str | None = None,
    ) -> None:
        #: Host name → IP for peers' advertised names (else: the name, or the master's address).
        self.hosts = {} if hosts is None else parse_hosts(hosts)
        self.master_uri = master_uri
        # Like rospy: an explicit option, else ROS_IP / ROS_HOSTNAME, else the route's address.
        self.host = host or os.environ.get("ROS_IP") or os.environ.get("ROS_HOSTNAME")
        self.bind = bind
        self.node_name = node_name or default_node_name()
        self.connect_timeout = connect_timeout
        self.rpc_timeout = rpc_timeout
        self.master_check_interval = master_check_interval
        self.name = name or master_uri
        self.node: RosNode | None = None
        #: Undecodable status messages over the channel's life (their bytes are in bytes_discarded).
        self.decode_errors = 0
        self._decoder_stats = DecoderStats()
        self._feed: Feed | None = None
        self._counted = NodeStats()
        self._goal_num: int | None = None

    def __repr__(self) -> str:
        return f"<RosChannel {self.name}>"

    @property
    def decoder_stats(self) -> DecoderStats:
        """Counted by the link per status; lost and undecodable messages counted here."""
        return self._decoder_stats

    def map_target_count(self) -> int | None:
        """``/galileo/goal_num`` as read at the last connect (dynamic targets included)."""
        return self._goal_num

    async def open(self, feed: Feed) -> None:
        """Start a node on the master, subscribed and advertised; read the target count."""
        await self._drop_node()
        self._feed = feed
        host = self.host or await local_address_for(self.master_uri)
        node = RosNode(
            self.master_uri,
            on_status=self._status_from_node,
            on_lost=feed.lost,
            host=host,
            bind=self.bind,
            name=self.node_name,
            connect_timeout=self.connect_timeout,
            rpc_timeout=self.rpc_timeout,
            master_check_interval=self.master_check_interval,
            hosts=self.hosts,
        )
        self._counted = NodeStats()
        # Kept even if start() fails: a start cancelled by an anyio scope cannot finish the
        # node's close (unregistering), so _drop_node finishes it when the link closes.
        self.node = node
        try:
            await node.start()
        except (GalileoConnectionError, OSError) as exc:  # foreign errors: at the link edge
            raise GalileoConnectionError(f"cannot connect to {self.name}: {exc}") from exc
        _log.info("connected to %s as %s", self.master_uri, node.name)
        await self._read_goal_num(node)

    async def _read_goal_num(self, node: RosNode) -> None:
        try:
            value = await node.get_param(GOAL_NUM_PARAM)
        except RosApiError as exc:  # keep what the last connect read
            _log.warning("cannot read %s from %s: %s", GOAL_NUM_PARAM, self.master_uri, exc)
            return
        # The vendor's navigation node stores it as a string ("5"); the SDK accepts an int too.
        if isinstance(value, str) and value.strip().isdigit():
            value = int(value)
        if value is None or isinstance(value, bool) or not isinstance(value, int):
            count = None
        else:
            count = value if 0 <= value <= _MAX_TARGETS else None
        if count is None and value is not None:
            _log.warning("ignoring %s = %r on %s", GOAL_NUM_PARAM, value, self.master_uri)
        self._goal_num = count

    def _status_from_node(self, status: GalileoStatus) -> None:
        if self.node is not None:
            self._count(self.node)
        if self._feed is not None:
            self._feed.status(status)

    def _count(self, node: RosNode) -> None:
        if self._feed is None:
            return
        decoder, counted, current = self._decoder_stats, self._counted, node.stats
        self._feed.stats.bytes_received += current.bytes_received - counted.bytes_received
        decoder.lost_frames += current.lost_messages - counted.lost_messages
        decoder.bytes_discarded += current.bytes_discarded - counted.bytes_discarded
        self.decode_errors += current.decode_errors - counted.decode_errors
        self._counted = dataclasses.replace(current)

    def abandon(self, reason: str) -> None:
        """Drop the node's connections (a frozen robot keeps its sockets open)."""
        if self.node is not None:
            # The node reports the loss; the link ignores its own second report.
            self.node.drop(ConnectionLost(reason))

    async def write(self, command: Command) -> None:
        """Publish ``command`` on /galileo/cmds, or a Velocity as a Twist on /cmd_vel."""
        if self.node is None:
            raise GalileoConnectionError(f"not connected to {self.master_uri}")
        if isinstance(command, Velocity):
            self.node.publish_velocity(command.linear, command.angular)
        else:
            self.node.publish(command)

    async def close(self) -> None:
        """Close the node (unregistering from the master, bounded)."""
        await self._drop_node()

    async def _drop_node(self) -> None:
        node = self.node
        if node is not None:
            self._count(node)
            try:
                await node.close()
            finally:  # kept until closed: a cancelled drop is finished by the next one
                if self.node is node:
                    self.node = None


def ros_channel(url: str, options: dict[str, Any]) -> RosChannel:
    """The channel of ``ros://host[:port]``; ``options``: checked, without the Link's."""
    master_uri, url_options = parse_ros_url(url)
    kept = {k: v for k, v in options.items() if k not in (*_IGNORED_OPTIONS, "layout")}
    return RosChannel(master_uri, name=url, **(url_options | kept))
