"""ros:// against a real master and a hand-built status publisher: odd definitions, bad bytes."""

from __future__ import annotations

import asyncio
import struct
from collections.abc import AsyncIterator
from pathlib import Path
from typing import Any

import pytest

from galileo_async.errors import GalileoConnectionError
from galileo_async.links import open_link
from galileo_async.models import NavStatus
from galileo_async.protocol.commands import Goto
from galileo_async.ros import (
    CMDS_TOPIC,
    STATUS_MD5,
    STATUS_TOPIC,
    STATUS_TYPE,
    RosChannel,
)
from galileo_async.ros.messages import CMDS_TYPE, STATUS_DEFINITION, full_definition
from galileo_async.ros.tcpros import TcprosPublisher, subscribe
from galileo_async.ros.xmlrpc import MasterClient, SlaveServer, request_topic
from galileo_async.state import StatusStore
from tests.support.ros_support import RosMaster

pytestmark = pytest.mark.timeout(30)

NEWER = "Header header\nint32 navStatus\nstring robotName\nfloat32 power\nint32 targetNumID\n"


class QuietPublisher(TcprosPublisher):
    """A publisher that sends no message_definition (only its md5 sum)."""

    def response_header(self) -> dict[str, str]:
        header = super().response_header()
        del header["message_definition"]
        return header


class FakeRobot:
    """The robot's ROS side built from the link's own pieces, fed by the test."""

    def __init__(self, master: RosMaster, publisher: TcprosPublisher) -> None:
        self.master_uri = f"http://127.0.0.1:{master.port}/"
        self.status = publisher
        self.slave = SlaveServer("/fake_robot", self.master_uri)
        self.master = MasterClient(self.master_uri, "/fake_robot")
        self.commands: asyncio.Queue[bytes] = asyncio.Queue()
        self.transports: list[asyncio.Transport] = []
        self.tasks: set[asyncio.Task[None]] = set()

    async def start(self) -> None:
        uri = await self.slave.start("127.0.0.1")
        port = await self.status.start("127.0.0.1")
        self.slave.publications[STATUS_TOPIC] = (STATUS_TYPE, ("127.0.0.1", port))
        self.slave.subscriptions[CMDS_TOPIC] = (CMDS_TYPE, self._publishers)
        await self.master.register_publisher(STATUS_TOPIC, STATUS_TYPE, uri)
        self._publishers(await self.master.register_subscriber(CMDS_TOPIC, CMDS_TYPE, uri))

    def _publishers(self, uris: list[str]) -> None:
        for uri in uris:
            task = asyncio.get_running_loop().create_task(self._subscribe(uri))
            self.tasks.add(task)
            task.add_done_callback(self.tasks.discard)

    async def _subscribe(self, uri: str) -> None:
        host, port = await request_topic(uri, "/fake_robot", CMDS_TOPIC, timeout=2)
        header = {"callerid": "/fake_robot", "topic": CMDS_TOPIC, "md5sum": "*", "type": "*"}
        transport, _ = await subscribe(
            host, port, header, self.commands.put_nowait, lambda exc: None, timeout=2
        )
        self.transports.append(transport)

    async def close(self) -> None:
        for task in list(self.tasks):
            task.cancel()
        await asyncio.gather(*self.tasks, return_exceptions=True)
        for transport in self.transports:
            transport.abort()
        await self.status.close()
        await self.slave.close()


@pytest.fixture
async def master(tmp_path: Path) -> AsyncIterator[RosMaster]:
    async with RosMaster.running(tmp_path) as master:
        yield master


async def feed(robot: FakeRobot, messages: list[bytes]) -> None:
    """Publish the messages at 100 Hz until cancelled (a robot publishes without pause)."""
    while True:
        for message in messages:
            robot.status.publish(message)
        await asyncio.sleep(0.01)


def header(seq: int) -> bytes:
    return struct.pack("<IIII", seq, 0, 0, 0)


async def test_newer_definition_with_unknown_fields_and_bad_messages(master: RosMaster) -> None:
    publisher = TcprosPublisher(
        topic=STATUS_TOPIC,
        msg_type=STATUS_TYPE,
        md5sum="f" * 32,
        definition=full_definition(NEWER),
        caller_id="/fake_robot",
    )
    robot = FakeRobot(master, publisher)
    await robot.start()
    good = header(1) + struct.pack("<iI", 1, 4) + b"r2d2" + struct.pack("<fi", 24.0, 6)
    bad = header(2) + struct.pack("<iI", 1, 1000)  # robotName runs past the end
    store = StatusStore()
    link = open_link(master.url, store, node_name="/driver", connect_timeout=3)
    sender = asyncio.create_task(feed(robot, [good, bad]))
    try:
        await link.open()
        status = await store.wait_until(lambda s: True, timeout=3)
        assert status.nav_status is NavStatus.OPEN
        assert status.power == 24.0
        assert status.target_num_id == 6
        assert status.visual_status is None
        channel = link.channel
        assert isinstance(channel, RosChannel)
        await store.wait_until(lambda s: channel.decode_errors > 0, timeout=3)
        # Messages are counted as messages, their bytes (with the length prefix) as bytes.
        assert link.stats.bytes_discarded == channel.decode_errors * (len(bad) + 4)
        assert link.stats.resyncs == 0
        assert link.connected
        await link.send(Goto(5))
        command = await asyncio.wait_for(robot.commands.get(), 3)
        # GalileoNativeCmds: header, length 2, data [g, 5]
        assert command.endswith(struct.pack("<II", 2, 2) + b"g\x05")
    finally:
        sender.cancel()
        await asyncio.gather(sender, return_exceptions=True)
        await link.close()
        await robot.close()


async def test_publisher_without_definition_uses_the_md5(master: RosMaster) -> None:
    publisher = QuietPublisher(
        topic=STATUS_TOPIC,
        msg_type=STATUS_TYPE,
        md5sum=STATUS_MD5,
        definition="",
        caller_id="/fake_robot",
    )
    robot = FakeRobot(master, publisher)
    await robot.start()
    fields = [line.split() for line in STATUS_DEFINITION.splitlines()[1:]]
    layout = "<" + "".join("f" if kind == "float32" else "i" for kind, _ in fields)
    values = dict.fromkeys((name for _, name in fields), 0) | {
        "power": 12.0,
        "targetNumID": 2,
        "currentPosX": 1.0,
        "currentPosY": 2.0,
    }
    message = header(3) + struct.pack(layout, *(values[name] for _, name in fields))
    store = StatusStore()
    link = open_link(master.url, store, connect_timeout=3)
    sender = asyncio.create_task(feed(robot, [message]))
    try:
        await link.open()
        status = await store.wait_until(lambda s: True, timeout=3)
        assert status.power == 12.0
        assert status.target_num_id == 2
        assert (status.current_pose_x, status.current_pose_y) == (1.0, 2.0)
        assert status.time_stamp == 3
    finally:
        sender.cancel()
        await asyncio.gather(sender, return_exceptions=True)
        await link.close()
        await robot.close()


async def test_wrong_message_type_is_refused(master: RosMaster) -> None:
    publisher = TcprosPublisher(
        topic=STATUS_TOPIC,
        msg_type="std_msgs/String",
        md5sum="992ce8a1687cec8c8bd883ec73ca41d1",
        definition="string data\n",
        caller_id="/fake_robot",
    )
    robot = FakeRobot(master, publisher)
    await robot.start()
    link = open_link(master.url, StatusStore(), connect_timeout=1)
    try:
        with pytest.raises(GalileoConnectionError, match="std_msgs/String"):
            await link.open()
    finally:
        await link.close()
        await robot.close()


class LatchedPublisher(TcprosPublisher):
    """Writes its last message to a new subscriber right behind the handshake reply.

    ROS latched topics do this; on loopback the reply and the message reach the subscriber
    in one read.
    """

    def __init__(self, latched: bytes, **kwargs: str) -> None:
        super().__init__(**kwargs)
        self.latched = latched

    def added(self, connection: Any) -> None:
        super().added(connection)
        connection.transport.write(struct.pack("<I", len(self.latched)) + self.latched)


async def test_a_status_in_the_same_read_as_the_handshake_reply_is_kept(
    master: RosMaster,
) -> None:
    """The only status the robot sends arrives with the header: it must reach the store."""
    status = header(1) + struct.pack("<iI", 1, 4) + b"r2d2" + struct.pack("<fi", 24.0, 6)
    publisher = LatchedPublisher(
        status,
        topic=STATUS_TOPIC,
        msg_type=STATUS_TYPE,
        md5sum="f" * 32,
        definition=full_definition(NEWER),
        caller_id="/fake_robot",
    )
    robot = FakeRobot(master, publisher)
    await robot.start()
    store = StatusStore()
    link = open_link(master.url, store, node_name="/driver", connect_timeout=3)
    try:
        await link.open()
        first = await store.wait_until(lambda s: True, timeout=3)
        assert first.power == 24.0
        assert first.target_num_id == 6
        channel = link.channel
        assert isinstance(channel, RosChannel)
        assert link.stats.decoder.frames == 1
    finally:
        await link.close()
        await robot.close()
