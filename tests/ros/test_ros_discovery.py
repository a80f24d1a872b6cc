"""Discovery: robots' UDP announcements (docs/protocol.md §3), from a broadcaster on loopback."""

from __future__ import annotations

import asyncio
import json
import socket
from collections.abc import Iterable

import pytest

from galileo_async.errors import GalileoConnectionError, InvalidArgument
from galileo_async.ros.discovery import DiscoveredRobot, discover, parse_announcement
from tests.support.cancel_ways import WAYS, stop_waiting
from tests.support.ros_support import free_port

pytestmark = pytest.mark.timeout(20)

ANNOUNCEMENT = {"id": "galileo-7", "port": 11311, "mac": "00:11:22:33:44:55", "version": "5.1"}
#: A 5.x robot with the HTTP API announces its port 3546 (docs/protocol.md §5.2).
HTTP_ANNOUNCEMENT = {"id": "galileo-8", "port": 3546, "version": "5.0.0"}


async def broadcast(port: int, datagrams: Iterable[bytes], period: float = 0.02) -> None:
    """Send the datagrams to 127.0.0.1:port over and over, like a robot at 10 Hz (faster)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.setblocking(False)
        while True:
            for datagram in datagrams:
                sock.sendto(datagram, ("127.0.0.1", port))
            await asyncio.sleep(period)


@pytest.fixture
def udp_port() -> int:
    return free_port(socket.SOCK_DGRAM)


async def discover_while_broadcasting(port: int, datagrams: list[bytes]) -> list[DiscoveredRobot]:
    sender = asyncio.create_task(broadcast(port, datagrams))
    try:
        return await discover(0.3, bind="127.0.0.1", port=port)
    finally:
        sender.cancel()
        await asyncio.gather(sender, return_exceptions=True)


async def test_discovers_a_broadcasting_robot(udp_port: int) -> None:
    robots = await discover_while_broadcasting(udp_port, [json.dumps(ANNOUNCEMENT).encode()])
    assert robots == [
        DiscoveredRobot(
            id="galileo-7", address="127.0.0.1", port=11311, mac="00:11:22:33:44:55", version="5.1"
        )
    ]
    assert robots[0].url == "ros://127.0.0.1:11311"


async def test_newer_firmware_announcing_its_http_port_still_gets_the_master_url(
    udp_port: int,
) -> None:
    # Newer firmware announces the port of its HTTP service; the ROS master stays at 11311.
    announcement = dict(ANNOUNCEMENT, port=3546)
    robots = await discover_while_broadcasting(udp_port, [json.dumps(announcement).encode()])
    assert [(r.id, r.port, r.master_port) for r in robots] == [("galileo-7", 3546, 11311)]
    assert robots[0].url == "ros://127.0.0.1:11311"


def port_is_free(port: int) -> bool:
    """True when a socket without SO_REUSEADDR can bind the UDP port (nobody holds it)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        try:
            sock.bind(("127.0.0.1", port))
        except OSError:
            return False
    return True


@pytest.mark.parametrize("how", WAYS)
async def test_cancelled_discover_releases_its_port(udp_port: int, how: str) -> None:
    await stop_waiting(how, lambda: discover(30, bind="127.0.0.1", port=udp_port), 0.05)
    assert port_is_free(udp_port)


async def test_garbage_is_ignored_and_robots_are_deduplicated(udp_port: int) -> None:
    other = dict(ANNOUNCEMENT, id="galileo-2", port=11312)
    datagrams = [
        b"\xff\xfe not json",
        b"[1, 2]",
        json.dumps({"port": 1}).encode(),
        json.dumps(dict(ANNOUNCEMENT, port="nope")).encode(),
        json.dumps(ANNOUNCEMENT).encode(),
        json.dumps(other).encode(),
    ]
    robots = await discover_while_broadcasting(udp_port, datagrams)
    assert [(r.id, r.port) for r in robots] == [("galileo-2", 11312), ("galileo-7", 11311)]


async def test_nothing_heard_is_an_empty_list(udp_port: int) -> None:
    assert await discover(0.05, bind="127.0.0.1", port=udp_port) == []


async def test_bad_arguments() -> None:
    with pytest.raises(InvalidArgument):
        await discover(0)
    with pytest.raises(GalileoConnectionError):
        await discover(0.05, bind="192.0.2.1", port=free_port(socket.SOCK_DGRAM))


def test_parse_announcement_fields() -> None:
    robot = parse_announcement(b'{"id": 5, "port": "11311"}', "10.0.0.8")
    assert robot == DiscoveredRobot(id="5", address="10.0.0.8", port=11311)
    assert parse_announcement(b'{"id": "x", "port": 0}', "h") is None
    assert parse_announcement(b'{"id": "x", "port": true}', "h") is None
    assert parse_announcement(b'{"id": "x"}', "::1") == DiscoveredRobot("x", "::1", 11311)
    assert DiscoveredRobot("x", "fe80::1", 11311).url == "ros://[fe80::1]:11311"
    assert DiscoveredRobot("x", "fe80::1", 11311).urls == ("ros://[fe80::1]:11311",)
    assert DiscoveredRobot("x", "10.0.0.8", 3546).urls == (
        "http://10.0.0.8:3546",
        "ros://10.0.0.8:11311",
    )
    assert parse_announcement(b"x" * 5000, "h") is None


def test_cli_discover_lists_the_robot_with_its_url(udp_port: int) -> None:
    import threading

    from typer.testing import CliRunner

    from galileo_async.cli import app

    stop = threading.Event()

    def announce() -> None:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
            while not stop.wait(0.02):
                for announcement in (ANNOUNCEMENT, HTTP_ANNOUNCEMENT):
                    sock.sendto(json.dumps(announcement).encode(), ("127.0.0.1", udp_port))

    sender = threading.Thread(target=announce, daemon=True)
    sender.start()
    try:
        args = ["discover", "--bind", "127.0.0.1", "--udp-port", str(udp_port), "-t", "0.3"]
        result = CliRunner().invoke(app, [*args, "--json"])
        plain = CliRunner().invoke(app, args)
    finally:
        stop.set()
        sender.join(timeout=5)
    assert result.exit_code == 0, result.output
    assert json.loads(result.stdout) == [
        {
            "id": "galileo-7",
            "url": "ros://127.0.0.1:11311",
            "urls": ["ros://127.0.0.1:11311"],
            "mac": ANNOUNCEMENT["mac"],
            "version": "5.1",
            "announced_port": 11311,
        },
        {
            "id": "galileo-8",
            "url": "ros://127.0.0.1:11311",
            "urls": ["http://127.0.0.1:3546", "ros://127.0.0.1:11311"],
            "mac": None,
            "version": "5.0.0",
            "announced_port": 3546,
        },
    ]
    assert plain.exit_code == 0
    assert "ros://127.0.0.1:11311" in plain.stdout
    assert "http://127.0.0.1:3546" in plain.stdout


def test_cli_discover_says_when_nothing_is_heard(udp_port: int) -> None:
    from typer.testing import CliRunner

    from galileo_async.cli import app

    args = ["discover", "--bind", "127.0.0.1", "--udp-port", str(udp_port), "-t", "0.1"]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0
    assert "no robot announced itself" in result.stderr
