"""ros:// when the robot's nodes advertise a host name this host cannot resolve (real ROS 1)."""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import AsyncIterator
from pathlib import Path

import pytest

from galileo_async.errors import GalileoConnectionError, InvalidArgument
from galileo_async.robot import Robot, connect
from galileo_async.ros import CMDS_TOPIC, parse_ros_url
from galileo_async.ros.hosts import PeerAddresses, parse_hosts
from galileo_async.ros.xmlrpc import xmlrpc_call
from tests.support.cancel_ways import WAYS, stop_waiting
from tests.support.ros_support import RobotNode, RosMaster, eventually

pytestmark = pytest.mark.timeout(60)

#: RFC 6761: names under .invalid never resolve.
UNRESOLVABLE = "robot-desktop.invalid"


@pytest.fixture
async def master(tmp_path: Path) -> AsyncIterator[RosMaster]:
    async with RosMaster.running(tmp_path) as master:
        yield master


async def cmds_publisher_registered(master: RosMaster) -> bool:
    """True once a node publishes /galileo/cmds on the master (ours, connecting)."""
    uri = f"http://127.0.0.1:{master.port}/"
    _, _, (publishers, _, _) = await xmlrpc_call(uri, "getSystemState", "/test", timeout=2)
    return any(topic == CMDS_TOPIC and nodes for topic, nodes in publishers)


@contextlib.asynccontextmanager
async def robot_behind_a_host_name(
    master: RosMaster, url: str, *, bind: str = "127.0.0.1", connect_timeout: float = 15
) -> AsyncIterator[Robot]:
    """Connect to ``url``, then start a robot node advertising UNRESOLVABLE, listening on bind.

    Our node registers first: the test's master cannot resolve the robot's name either, so it
    could not tell the robot node about a publisher registered after it (on a real robot the
    master runs on that host and can).
    """
    opening = asyncio.ensure_future(connect(url, connect_timeout=connect_timeout))
    try:
        await eventually(lambda: cmds_publisher_registered(master), 10, "our registration")
        async with RobotNode.running(master, "--hostname", UNRESOLVABLE, "--bind", bind):
            robot = await asyncio.wait_for(asyncio.shield(opening), 20)
            try:
                yield robot
            finally:
                await robot.close()
    finally:
        opening.cancel()
        with contextlib.suppress(BaseException):
            await opening


async def test_unresolvable_publisher_host_falls_back_to_the_master_address(
    master: RosMaster,
) -> None:
    async with robot_behind_a_host_name(master, master.url) as robot:
        link = robot.link
        assert link.frames > 0
        await robot.start_navigation(timeout=10)
        result = await robot.goto(1, timeout=10)
        assert result.target_id == 1


async def test_the_hosts_map_in_the_url_overrides_the_master_address(master: RosMaster) -> None:
    # The robot listens on 127.0.0.2 only: the master's address (127.0.0.1) would not reach it.
    url = f"{master.url}?hosts={UNRESOLVABLE}=127.0.0.2"
    async with robot_behind_a_host_name(master, url, bind="127.0.0.2") as robot:
        await robot.start_navigation(timeout=10)
        assert (await robot.goto(2, timeout=10)).target_id == 2


@pytest.mark.parametrize("how", WAYS)
async def test_a_cancelled_connect_with_a_hosts_map_leaves_nothing_registered(
    master: RosMaster, how: str
) -> None:
    url = f"{master.url}?hosts={UNRESOLVABLE}=127.0.0.2"

    async def opening() -> None:
        async with connect(url, connect_timeout=20):
            pytest.fail("no robot node runs: connect cannot succeed")

    await stop_waiting(how, opening, 0.3)  # connect waits for a robot that never comes
    assert not await cmds_publisher_registered(master)


@pytest.mark.parametrize(
    "query",
    ["robot", "robot=", "=10.0.0.5", "robot=not-an-ip", "bad!name=10.0.0.5", "a=10.0.0.5,",
     "a=10.0.0.5,A=10.0.0.6", "a=10.0.0.5;b=10.0.0.6"],
)  # fmt: skip
async def test_a_malformed_hosts_map_is_refused_before_anything_opens(query: str) -> None:
    # Port 1: had anything been opened, the error would be a connection error.
    with pytest.raises(InvalidArgument, match="hosts"):
        await connect(f"ros://127.0.0.1:1?hosts={query}")


@pytest.mark.parametrize("hosts", [123, {"robot": 5}, {"robot": "x"}, {"": "10.0.0.5"}])
async def test_a_malformed_hosts_option_is_refused_before_anything_opens(hosts: object) -> None:
    with pytest.raises(InvalidArgument, match="hosts"):
        await connect("ros://127.0.0.1:1", hosts=hosts)


def test_hosts_map_syntax() -> None:
    assert parse_hosts("Robot-Desktop=10.0.0.5, xiaoqiang_desktop=::1") == {
        "robot-desktop": "10.0.0.5",
        "xiaoqiang_desktop": "::1",
    }
    assert parse_hosts({"robot.lan.": "[fe80::1]"}) == {"robot.lan": "fe80::1"}
    _, options = parse_ros_url("ros://10.0.0.5?hosts=robot=10.0.0.5")
    assert options == {"hosts": {"robot": "10.0.0.5"}}


async def test_peer_addresses_keep_what_resolves_and_replace_what_does_not() -> None:
    peers = PeerAddresses({"robot-desktop": "10.0.0.7"}, fallback="::1")
    assert await peers.address("ROBOT-DESKTOP") == "10.0.0.7"
    assert await peers.address("10.1.2.3") == "10.1.2.3"
    assert await peers.address("localhost") == "localhost"
    assert await peers.address(UNRESOLVABLE) == "::1"
    assert await peers.uri(f"http://{UNRESOLVABLE}:4567/") == "http://[::1]:4567/"
    assert await peers.uri("http://localhost:4567/") == "http://localhost:4567/"


async def test_without_the_fallback_an_unreachable_robot_is_a_connection_error(
    master: RosMaster,
) -> None:
    # The robot listens on 127.0.0.2 and no map says so: the master's address is tried.
    behind = robot_behind_a_host_name(master, master.url, bind="127.0.0.2", connect_timeout=2)
    with pytest.raises(GalileoConnectionError, match="cannot subscribe to /galileo/status"):
        async with behind:
            pass
