"""ros:// against a real ROS 1 master: connection failures, restarts, registration."""

from __future__ import annotations

import signal
from collections.abc import AsyncIterator
from pathlib import Path

import pytest

import galileo_async as galileo
from galileo_async.errors import ConnectionLost, GalileoConnectionError, LinkStale
from galileo_async.links import open_link
from galileo_async.protocol.commands import Goto, StartNavigation
from galileo_async.robot import Robot
from galileo_async.ros import CMDS_TOPIC, STATUS_TOPIC, RosChannel
from galileo_async.ros.xmlrpc import xmlrpc_call
from galileo_async.state import StatusStore
from tests.support.ports import refused_port
from tests.support.ros_support import RobotNode, RosMaster, eventually

pytestmark = pytest.mark.timeout(60)


@pytest.fixture
async def master(tmp_path: Path) -> AsyncIterator[RosMaster]:
    async with RosMaster.running(tmp_path) as master:
        yield master


async def registered(master: RosMaster, node_name: str) -> bool:
    """True when node_name publishes /galileo/cmds and subscribes /galileo/status."""
    try:
        code, _, (publishers, subscribers, _) = await xmlrpc_call(
            f"http://127.0.0.1:{master.port}/", "getSystemState", "/test", timeout=1.0
        )
    except GalileoConnectionError:
        return False
    pubs = dict((topic, nodes) for topic, nodes in publishers)
    subs = dict((topic, nodes) for topic, nodes in subscribers)
    return (
        code == 1
        and node_name in pubs.get(CMDS_TOPIC, [])
        and node_name in subs.get(STATUS_TOPIC, [])
    )


def ros_link(robot: Robot) -> RosChannel:
    channel = robot._link.channel
    assert isinstance(channel, RosChannel)
    return channel


async def test_link_without_robot_fails_open_and_cleans_up(master: RosMaster) -> None:
    store = StatusStore()
    link = open_link(master.url, store, connect_timeout=0.5, node_name="/lonely")
    with pytest.raises(GalileoConnectionError, match="/galileo/status"):
        await link.open()
    assert not await registered(master, "/lonely")  # it unregistered on the way out
    await link.close()


async def test_link_without_master_fails_open(tmp_path: Path) -> None:
    store = StatusStore()
    with refused_port() as port:
        link = open_link(f"ros://127.0.0.1:{port}", store, rpc_timeout=0.5)
        with pytest.raises(GalileoConnectionError, match="getPid"):
            await link.open()
        await link.close()


async def test_raw_link_sends_and_counts(master: RosMaster) -> None:
    async with RobotNode.running(master):
        store = StatusStore()
        link = open_link(master.url, store, node_name="/raw_link", host="127.0.0.1")
        try:
            await link.open()
            assert await registered(master, "/raw_link")
            await link.send(StartNavigation())
            await store.wait_until(lambda s: s.visual_initialised, timeout=5)
            with store.watch() as watch:
                await link.send(Goto(1))
                while True:
                    status = await watch.next(5)
                    if status.target_num_id == 1 and status.target_status == 0:
                        break
            stats = link.stats
            assert stats.commands_sent == 2
            assert stats.connected
            assert stats.frames > 10
            assert stats.bytes_received > 0
            assert stats.lost_frames == 0
        finally:
            await link.close()
        assert not await registered(master, "/raw_link")


async def test_master_and_robot_restart_reconnects(master: RosMaster) -> None:
    node = RobotNode(master)
    await node.start()
    try:
        async with galileo.connect(
            master.url, reconnect_max=0.3, connect_timeout=2.0, stale_timeout=0.5
        ) as robot:
            await robot.start_navigation(timeout=10)
            await robot.goto(0, timeout=10)
            await node.stop()
            await master.stop()
            await eventually(lambda: not robot.link.connected, 5, "the link to drop")
            await master.start()
            await node.start()
            await eventually(lambda: robot.link.connected, 15, "the link to reconnect")
            assert robot.link.reconnects >= 1
            # Connected again means a status of the restarted robot is already in hand.
            assert robot.status is not None
            assert not robot.status.navigating
            await robot.start_navigation(timeout=10)
            result = await robot.goto(1, timeout=10)
            assert result.target_id == 1
    finally:
        await node.stop()


async def test_master_restart_alone_keeps_the_link_and_registers_again(
    master: RosMaster,
) -> None:
    async with (
        RobotNode.running(master),
        galileo.connect(
            master.url, node_name="/survivor", master_check_interval=0.1, stale_timeout=5.0
        ) as robot,
    ):
        await robot.start_navigation(timeout=10)
        await master.stop()
        await master.start()
        # Topic connections are peer to peer: status keeps flowing without the master.
        await eventually(lambda: registered(master, "/survivor"), 10, "re-registration")
        link = ros_link(robot)
        assert link.node is not None
        assert link.node.stats.master_restarts >= 1
        assert robot.link.connected
        assert robot.link.reconnects == 0
        result = await robot.goto(2, timeout=10)
        assert result.target_id == 2


async def test_robot_node_restart_reconnects(master: RosMaster) -> None:
    node = RobotNode(master)
    await node.start()
    try:
        async with galileo.connect(master.url, reconnect_max=0.3, connect_timeout=2.0) as robot:
            await robot.start_navigation(timeout=10)
            await node.stop()
            await eventually(lambda: not robot.link.connected, 5, "the link to drop")
            with pytest.raises(ConnectionLost):
                await robot.goto(0, timeout=5)
            await node.start()
            await eventually(lambda: robot.link.connected, 15, "the link to reconnect")
            assert robot.status is not None
            assert not robot.status.navigating
            await robot.start_navigation(timeout=10)
            result = await robot.goto(3, timeout=10)
            assert result.target_id == 3
    finally:
        await node.stop()


async def test_frozen_robot_makes_the_link_stale(master: RosMaster) -> None:
    async with (
        RobotNode.running(master) as node,
        galileo.connect(master.url, stale_timeout=0.3) as robot,
    ):
        assert node.proc is not None
        node.proc.send_signal(signal.SIGSTOP)
        try:
            with pytest.raises(LinkStale):
                await robot.wait_until(lambda s: s.navigating, timeout=5)
            assert robot.link.stale
        finally:
            node.proc.send_signal(signal.SIGCONT)
        await eventually(lambda: not robot.link.stale, 5, "fresh status")
        assert robot.link.connected
        assert robot.link.reconnects == 0
