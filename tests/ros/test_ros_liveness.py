"""ros:// against a real master: peers that die silently, and closing when the master hangs."""

from __future__ import annotations

import asyncio
import contextlib
import signal
from collections.abc import AsyncIterator, Iterator
from pathlib import Path
from urllib.parse import urlsplit

import pytest

import galileo_async as galileo
from galileo_async.errors import InvalidArgument
from galileo_async.links import open_link
from galileo_async.robot import Robot
from galileo_async.ros import RosChannel
from galileo_async.ros.node import CLOSE_BOUND
from galileo_async.state import StatusStore
from galileo_async.transports import Link
from tests.support.ros_support import RobotNode, RosMaster, eventually, refuses_connections

pytestmark = pytest.mark.timeout(60)


@pytest.fixture
async def master(tmp_path: Path) -> AsyncIterator[RosMaster]:
    async with RosMaster.running(tmp_path) as master:
        yield master


def ros_link(robot: Robot) -> RosChannel:
    channel = robot._link.channel
    assert isinstance(channel, RosChannel)
    return channel


def publisher_uri(robot: Robot) -> str:
    node = ros_link(robot).node
    assert node is not None
    assert node.publisher_uri is not None
    return node.publisher_uri


@contextlib.contextmanager
def frozen(proc: asyncio.subprocess.Process | None) -> Iterator[None]:
    """SIGSTOP a process: its sockets stay open but nothing answers; SIGCONT on exit."""
    assert proc is not None
    proc.send_signal(signal.SIGSTOP)
    try:
        yield
    finally:
        proc.send_signal(signal.SIGCONT)


async def drive(robot: Robot, target: int) -> None:
    """Commands reach the robot and its status comes back."""
    await robot.start_navigation(timeout=10)
    result = await robot.goto(target, timeout=10)
    assert result.target_id == target


async def test_robot_node_replaced_while_the_old_one_hangs(master: RosMaster) -> None:
    """The master's publisherUpdate, not the stale watchdog, moves the link to the new node."""
    old, new = RobotNode(master), RobotNode(master)
    await old.start()
    try:
        async with galileo.connect(
            master.url, reconnect_max=0.3, connect_timeout=3.0,
            stale_timeout=30.0, stale_reconnect=None,
        ) as robot:  # fmt: skip
            old_uri = publisher_uri(robot)
            with frozen(old.proc):
                # Same node name: the master drops the old registration and tells us.
                await new.start()
                await eventually(
                    lambda: robot.link.connected and robot.link.reconnects >= 1,
                    10, "the link to move to the new node",
                )  # fmt: skip
                assert publisher_uri(robot) != old_uri
                assert not robot.link.stale
                await drive(robot, 1)
    finally:
        await new.stop()
        await old.stop()


async def test_another_status_publisher_alone_changes_nothing(master: RosMaster) -> None:
    """A second publisher appearing is no reason to leave a live one."""
    async with (
        RobotNode.running(master),
        galileo.connect(master.url, connect_timeout=3.0) as robot,
    ):
        uri = publisher_uri(robot)
        async with RobotNode.running(master, "--name", "second_robot"):
            node = ros_link(robot).node
            assert node is not None
            await eventually(lambda: len(node._publishers) == 2, 10, "the publisherUpdate")
            assert robot.link.connected
            assert robot.link.reconnects == 0
            assert publisher_uri(robot) == uri
            assert node.stats.publisher_replaced == 0


async def test_frozen_robot_is_given_up_and_reconnected_when_it_resumes(
    master: RosMaster,
) -> None:
    async with (
        RobotNode.running(master) as node,
        galileo.connect(
            master.url, stale_timeout=0.2, stale_reconnect=3, reconnect_max=0.3,
            connect_timeout=1.0, rpc_timeout=0.5,
        ) as robot,
    ):  # fmt: skip
        with frozen(node.proc):
            await eventually(lambda: robot.link.stale, 5, "the link to go stale")
            await eventually(lambda: not robot.link.connected, 5, "the link to give up")
        await eventually(lambda: robot.link.connected, 15, "the link to reconnect")
        assert robot.link.reconnects >= 1
        assert not robot.link.stale
        await drive(robot, 2)


async def test_frozen_robot_is_given_up_for_a_new_robot_node(master: RosMaster) -> None:
    old = RobotNode(master)
    await old.start()
    try:
        async with galileo.connect(
            master.url, stale_timeout=0.2, stale_reconnect=3, reconnect_max=0.3,
            connect_timeout=2.0, rpc_timeout=0.5,
        ) as robot:  # fmt: skip
            old_uri = publisher_uri(robot)
            with frozen(old.proc):
                # Another name: the old registration stays, so no publisherUpdate drops it.
                async with RobotNode.running(master, "--name", "galileo_serial_server_2"):
                    await eventually(
                        lambda: robot.link.connected and robot.link.reconnects >= 1,
                        15, "the link to reach the new node",
                    )  # fmt: skip
                    assert publisher_uri(robot) != old_uri
                    await drive(robot, 3)
    finally:
        await old.stop()


async def test_stale_without_reconnect_when_disabled(master: RosMaster) -> None:
    async with (
        RobotNode.running(master) as node,
        galileo.connect(master.url, stale_timeout=0.1, stale_reconnect=None) as robot,
    ):
        with frozen(node.proc):
            await eventually(lambda: robot.link.stale, 5, "the link to go stale")
            # Ten times the stale timeout: with the default factor it would have reconnected.
            await asyncio.sleep(1.0)
            assert robot.link.connected
        await eventually(lambda: not robot.link.stale, 5, "fresh status")
        assert robot.link.reconnects == 0


def test_stale_reconnect_must_be_at_least_one_stale_timeout() -> None:
    with pytest.raises(InvalidArgument, match="stale_reconnect"):
        Link(RosChannel("http://127.0.0.1:11311/"), StatusStore(), stale_reconnect=0.5)


@pytest.mark.parametrize("how", ["frozen", "killed"])
async def test_close_releases_local_sockets_first_when_the_master_is_gone(
    master: RosMaster, how: str
) -> None:
    async with RobotNode.running(master):
        link = open_link(master.url, StatusStore(), host="127.0.0.1", node_name="/closer")
        await link.open()
        assert isinstance(link.channel, RosChannel)
        node = link.channel.node
        assert node is not None
        assert node._slave.uri is not None
        slave_port = urlsplit(node._slave.uri).port
        cmds_port = node._cmds.port
        assert slave_port is not None
        assert cmds_port is not None
        assert not await refuses_connections(slave_port)
        assert master.proc is not None
        with contextlib.ExitStack() as stack:
            if how == "frozen":  # connections are accepted, calls never answered
                stack.enter_context(frozen(master.proc))
            else:
                await master.stop()
            loop = asyncio.get_running_loop()
            started = loop.time()
            closing = asyncio.create_task(link.close())
            try:
                # Released before the unregister calls end (a frozen master makes them hang).
                await eventually(
                    lambda: refuses_connections(slave_port), 0.4, "the slave port to close"
                )
                assert await refuses_connections(cmds_port)
                await asyncio.wait_for(asyncio.shield(closing), CLOSE_BOUND + 1.0)
            finally:
                closing.cancel()
                await asyncio.gather(closing, return_exceptions=True)
            assert loop.time() - started < CLOSE_BOUND + 0.5
        assert await refuses_connections(slave_port)
        assert await refuses_connections(cmds_port)
