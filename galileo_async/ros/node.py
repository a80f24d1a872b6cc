"""A minimal ROS 1 node for the Galileo topics: publishes the commands, subscribes the status."""

from __future__ import annotations

import asyncio
import contextlib
import ipaddress
import itertools
import logging
import os
import time
from collections.abc import Awaitable, Callable, Coroutine, Mapping
from dataclasses import dataclass
from typing import Any
from urllib.parse import urlsplit

from ..errors import ConnectionLost, GalileoConnectionError
from ..models import GalileoStatus
from ..options import DEFAULT_CONNECT_TIMEOUT, DEFAULT_MASTER_CHECK_INTERVAL, DEFAULT_RPC_TIMEOUT
from ..protocol.commands import Command
from .hosts import PeerAddresses
from .messages import (
    CMD_VEL_TOPIC,
    CMDS_DEFINITION,
    CMDS_MD5,
    CMDS_TOPIC,
    CMDS_TYPE,
    STATUS_TOPIC,
    STATUS_TYPE,
    TWIST_DEFINITION,
    TWIST_MD5,
    TWIST_TYPE,
    StatusMessageDecoder,
    encode_cmds,
    encode_twist,
    full_definition,
)
from .msgdef import MessageDefinitionError
from .tcpros import TcprosPublisher, subscribe
from .xmlrpc import MasterClient, RosApiError, SlaveServer, http_uri, request_topic

__all__ = [
    "CLOSE_BOUND",
    "DEFAULT_CONNECT_TIMEOUT",
    "DEFAULT_MASTER_CHECK_INTERVAL",
    "DEFAULT_RPC_TIMEOUT",
    "NodeStats",
    "RosNode",
    "default_node_name",
]

_log = logging.getLogger(__name__)

#: Bound on everything close() awaits (unregistering, servers closing): within the Link's.
CLOSE_BOUND = 1.0

_node_numbers = itertools.count(1)


def default_node_name() -> str:
    """A caller id unique within this process (several links may share one master)."""
    return f"/galileo_async_{os.getpid()}_{next(_node_numbers)}"


@dataclass
class NodeStats:
    """Counters of one node's status subscription."""

    messages: int = 0
    bytes_received: int = 0
    #: Messages that arrived whole but could not be decoded (a count of messages).
    decode_errors: int = 0
    #: Bytes of those messages, framing included.
    bytes_discarded: int = 0
    lost_messages: int = 0
    master_restarts: int = 0
    #: Times the node dropped a publisher the master no longer lists (a new one replaced it).
    publisher_replaced: int = 0


class RosNode:
    """One connection to a robot over ROS 1: register, connect both topics, watch the master."""

    def __init__(
        self,
        master_uri: str,
        *,
        on_status: Callable[[GalileoStatus], None],
        on_lost: Callable[[BaseException | None], None],
        host: str,
        bind: str | None = None,
        name: str | None = None,
        connect_timeout: float = DEFAULT_CONNECT_TIMEOUT,
        rpc_timeout: float = DEFAULT_RPC_TIMEOUT,
        master_check_interval: float = DEFAULT_MASTER_CHECK_INTERVAL,
        hosts: Mapping[str, str] | None = None,
    ) -> None:
        self.master_uri = master_uri
        self.name = name or default_node_name()
        self.host = host
        self.bind = bind or (host if _is_ip(host) else "0.0.0.0")
        self.connect_timeout = connect_timeout
        self.rpc_timeout = rpc_timeout
        self.master_check_interval = master_check_interval
        self.stats = NodeStats()
        self.decoder: StatusMessageDecoder | None = None
        self.publisher_uri: str | None = None
        self._on_status = on_status
        self._on_lost = on_lost
        self._master = MasterClient(master_uri, self.name, timeout=rpc_timeout)
        self._peers = PeerAddresses(hosts or {}, urlsplit(master_uri).hostname or "127.0.0.1")
        self._slave = SlaveServer(self.name, master_uri)
        self._cmds = TcprosPublisher(
            topic=CMDS_TOPIC,
            msg_type=CMDS_TYPE,
            md5sum=CMDS_MD5,
            definition=full_definition(CMDS_DEFINITION),
            caller_id=self.name,
        )
        self._cmd_vel = TcprosPublisher(
            topic=CMD_VEL_TOPIC, msg_type=TWIST_TYPE, md5sum=TWIST_MD5,
            definition=TWIST_DEFINITION, caller_id=self.name,
        )  # fmt: skip
        self._status_transport: asyncio.Transport | None = None
        self._publishers: list[str] = []
        self._publishers_changed = asyncio.Event()
        self._first_status = asyncio.Event()
        self._watch_task: asyncio.Task[None] | None = None
        self._close_task: asyncio.Future[None] | None = None
        self._master_pid: int | None = None
        self._last_seq: int | None = None
        self._seq = 0
        self._up = False
        self._closed = False

    def __repr__(self) -> str:
        return f"<RosNode {self.name} at {self.master_uri}>"

    async def start(self) -> None:
        """Register, connect to the status publisher, wait for a cmds subscriber; or raise."""
        try:
            await self._start()
        except BaseException:
            await self.close()
            raise

    async def _start(self) -> None:
        slave_uri = await self._slave.start(self.bind)
        if self.bind != self.host:
            slave_uri = http_uri(self.host, urlsplit(slave_uri).port or 0)
        self._slave.uri = slave_uri
        port = await self._cmds.start(self.bind)
        self._slave.publications[CMDS_TOPIC] = (CMDS_TYPE, (self.host, port))
        port = await self._cmd_vel.start(self.bind)
        self._slave.publications[CMD_VEL_TOPIC] = (TWIST_TYPE, (self.host, port))
        self._slave.subscriptions[STATUS_TOPIC] = (STATUS_TYPE, self._publisher_update)
        self._master_pid = await self._master.get_pid()
        await self._register(slave_uri)
        loop = asyncio.get_running_loop()
        deadline = loop.time() + self.connect_timeout
        await self._connect_status(deadline)
        if not await self._cmds.wait_for_subscriber(max(0.0, deadline - loop.time())):
            raise GalileoConnectionError(
                f"nobody subscribed to {CMDS_TOPIC} on {self.master_uri} within "
                f"{self.connect_timeout} s (is the robot's galileo_serial_server running?)"
            )
        # Up means a status from this connection is in hand: after a reconnect, nothing
        # may act on the last status of the previous one.
        try:
            await asyncio.wait_for(self._first_status.wait(), max(0.01, deadline - loop.time()))
        except asyncio.TimeoutError:
            raise GalileoConnectionError(
                f"subscribed to {STATUS_TOPIC} on {self.master_uri}, but no valid status "
                f"arrived within {self.connect_timeout} s"
            ) from None
        self._cmds.on_change = self._cmds_subscribers_changed
        self._up = True
        self._watch_task = loop.create_task(self._watch_master(slave_uri), name=f"{self!r} master")

    async def _register(self, slave_uri: str) -> None:
        await self._master.register_publisher(CMDS_TOPIC, CMDS_TYPE, slave_uri)
        await self._master.register_publisher(CMD_VEL_TOPIC, TWIST_TYPE, slave_uri)
        self._publishers = await self._master.register_subscriber(
            STATUS_TOPIC, STATUS_TYPE, slave_uri
        )

    def _publisher_update(self, publishers: list[str]) -> None:
        self._publishers = publishers
        self._publishers_changed.set()
        current = self.publisher_uri
        if self._up and publishers and current is not None and current not in publishers:
            # The robot's node was restarted under a new URI while our TCP connection to the
            # old one lingers (a frozen or vanished host sends no FIN): take the new one.
            self.stats.publisher_replaced += 1
            self.drop(
                ConnectionLost(
                    f"the {STATUS_TOPIC} publisher {current} was replaced by {publishers[-1]}"
                )
            )

    def drop(self, reason: BaseException) -> None:
        """Give the connection up now: stop taking statuses and report it lost (idempotent)."""
        if not self._up or self._closed:
            return
        self._up = False
        transport, self._status_transport = self._status_transport, None
        if transport is not None:
            transport.abort()
        self._on_lost(reason)

    async def _connect_status(self, deadline: float) -> None:
        loop = asyncio.get_running_loop()
        last_error: Exception | None = None
        while True:
            self._publishers_changed.clear()
            # The newest registration is last: a restarted robot's node replaces a dead one.
            for uri in reversed(self._publishers):
                try:
                    await self._subscribe_at(uri, deadline)
                    return
                except (GalileoConnectionError, MessageDefinitionError) as exc:
                    last_error = exc
                    _log.info("status publisher %s: %s", uri, exc)
            remaining = deadline - loop.time()
            if remaining <= 0:
                reason = f": {last_error}" if last_error else " (no publisher registered)"
                raise GalileoConnectionError(
                    f"cannot subscribe to {STATUS_TOPIC} on {self.master_uri}{reason}"
                )
            with contextlib.suppress(asyncio.TimeoutError):
                await asyncio.wait_for(self._publishers_changed.wait(), min(remaining, 0.5))

    async def _subscribe_at(self, slave_uri: str, deadline: float) -> None:
        remaining = max(0.01, deadline - asyncio.get_running_loop().time())
        timeout = min(self.rpc_timeout, remaining)
        # The robot's nodes advertise its host name, which this host may not resolve.
        reachable_uri = await self._peers.uri(slave_uri)
        host, port = await request_topic(reachable_uri, self.name, STATUS_TOPIC, timeout=timeout)
        host = await self._peers.address(host)
        header = {
            "callerid": self.name,
            "topic": STATUS_TOPIC,
            "md5sum": "*",  # accept every version of GalileoStatus, decoded by field names
            "type": STATUS_TYPE,
            "tcp_nodelay": "1",
        }
        self.decoder = None
        transport, _ = await subscribe(
            host,
            port,
            header,
            self._on_message,
            self._on_status_closed,
            timeout=timeout,
            on_handshake=self._set_decoder,
        )
        self._status_transport = transport
        self.publisher_uri = slave_uri
        self._last_seq = None

    def _set_decoder(self, reply: dict[str, str]) -> None:
        """Set the decoder from the publisher's header, before its first message arrives."""
        kind = reply.get("type", STATUS_TYPE)
        if kind.rsplit("/", 1)[-1] != "GalileoStatus":
            raise MessageDefinitionError(f"{STATUS_TOPIC} carries {kind}, not GalileoStatus")
        self.decoder = StatusMessageDecoder(reply.get("message_definition"), reply.get("md5sum"))

    def _on_message(self, data: bytes) -> None:
        stats = self.stats
        stats.bytes_received += len(data) + 4
        decoder = self.decoder
        if decoder is None:
            return
        try:
            status = decoder.decode(data)
        except MessageDefinitionError:
            stats.decode_errors += 1
            stats.bytes_discarded += len(data) + 4
            return
        stats.messages += 1
        seq = status.time_stamp
        if seq is not None and self._last_seq is not None and seq > self._last_seq + 1:
            stats.lost_messages += seq - self._last_seq - 1
        self._last_seq = seq
        self._first_status.set()
        self._on_status(status)

    def _on_status_closed(self, exc: Exception | None) -> None:
        self._status_transport = None
        if self._up and not self._closed:
            self._up = False
            self._on_lost(exc or ConnectionLost(f"the {STATUS_TOPIC} publisher closed"))

    def _cmds_subscribers_changed(self, count: int) -> None:
        if count == 0 and self._up and not self._closed:
            self._up = False
            self._on_lost(ConnectionLost(f"the robot stopped subscribing to {CMDS_TOPIC}"))

    async def _watch_master(self, slave_uri: str) -> None:
        """Poll the master; when it comes back with another pid, register again."""
        while not self._closed:
            await asyncio.sleep(self.master_check_interval)
            try:
                pid = await self._master.get_pid()
                if pid != self._master_pid:
                    _log.info("master %s restarted: registering again", self.master_uri)
                    await self._register(slave_uri)
                    self._master_pid = pid
                    self.stats.master_restarts += 1
            except RosApiError as exc:
                _log.debug("master %s unreachable: %s", self.master_uri, exc)

    async def get_param(self, key: str) -> Any:
        """A parameter from the master's parameter server; None when it is not set."""
        return await self._master.get_param(key)

    def publish(self, command: Command) -> None:
        """Publish one command as GalileoNativeCmds; raise ConnectionLost if nobody listens."""
        if not self._up:
            raise ConnectionLost(f"not connected to {self.master_uri}")
        self._seq += 1
        message = encode_cmds(command, seq=self._seq, stamp=time.time())
        if self._cmds.publish(message) == 0:
            raise ConnectionLost(f"nobody subscribes to {CMDS_TOPIC}")

    def publish_velocity(self, linear: float, angular: float) -> None:
        """Publish one Twist on /cmd_vel (no subscriber yet: nobody gets it, as with rospy)."""
        if not self._up:
            raise ConnectionLost(f"not connected to {self.master_uri}")
        self._cmd_vel.publish(encode_twist(linear, angular))

    async def close(self) -> None:
        """Release every socket and task, then unregister (best effort); bounded by CLOSE_BOUND.

        The sockets are released at once; the rest runs as one task, which a cancelled caller
        leaves running (an anyio scope cancels every await): awaiting close() again finishes it.
        """
        if self._close_task is None:
            self._closed = True
            self._up = False
            # Local sockets first, synchronously: an unreachable master must not leave them open.
            if self._status_transport is not None:
                self._status_transport.abort()
                self._status_transport = None
            self._cmds.stop()
            self._cmd_vel.stop()
            self._slave.stop()
            self._close_task = asyncio.ensure_future(self._finish_close())
        await asyncio.shield(self._close_task)

    async def _finish_close(self) -> None:
        if self._watch_task is not None:
            self._watch_task.cancel()
            await asyncio.gather(self._watch_task, return_exceptions=True)
            self._watch_task = None
        waits: list[Coroutine[Any, Any, None]] = [
            self._cmds.close(), self._cmd_vel.close(), self._slave.close()
        ]  # fmt: skip
        slave_uri = self._slave.uri
        if slave_uri is not None and self._master_pid is not None:
            self._master.timeout = min(self.rpc_timeout, CLOSE_BOUND)
            waits.append(self._unregister(self._master.unregister_subscriber, STATUS_TOPIC))
            waits.append(self._unregister(self._master.unregister_publisher, CMDS_TOPIC))
            waits.append(self._unregister(self._master.unregister_publisher, CMD_VEL_TOPIC))
        tasks = [asyncio.ensure_future(wait) for wait in waits]
        try:
            _, pending = await asyncio.wait(tasks, timeout=CLOSE_BOUND)
            if pending:
                _log.debug("closing %r: %d steps cut at %.1f s", self, len(pending), CLOSE_BOUND)
        finally:  # no task may outlive it
            for task in tasks:
                task.cancel()
            await asyncio.gather(*tasks, return_exceptions=True)

    async def _unregister(
        self, unregister: Callable[[str, str], Awaitable[None]], topic: str
    ) -> None:
        slave_uri = self._slave.uri
        assert slave_uri is not None
        try:
            await unregister(topic, slave_uri)
        except RosApiError as exc:
            _log.debug("unregistering %s from %s: %s", topic, self.master_uri, exc)


def _is_ip(host: str) -> bool:
    try:
        ipaddress.ip_address(host)
    except ValueError:
        return False
    return True
