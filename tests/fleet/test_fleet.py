"""connect_fleet: concurrent connects, per-robot state, each(), merged streams, every exit path."""

from __future__ import annotations

import asyncio
import socket
from collections.abc import AsyncIterator
from typing import ClassVar

import anyio
import pytest

from galileo_async import Fleet, FleetResult, LinkState, Robot, connect_fleet
from galileo_async import events as ev
from galileo_async.errors import InvalidArgument, NotReady
from galileo_async.sim import Simulator
from tests.support.cancel_ways import WAYS, stop_waiting
from tests.support.fake_device import status_frame

WAIT = 10.0
SIM = "sim://?speed=50"


def closed_port() -> str:
    """A loopback URL nobody listens on (refused at once)."""
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    return f"socket://127.0.0.1:{port}"


@pytest.fixture
async def fleet() -> AsyncIterator[Fleet]:
    # connect's own timeouts bound the entry (a cancel scope cannot span a fixture's yield)
    async with connect_fleet({"a": SIM, "b": SIM, "c": SIM}) as connected:
        yield connected


async def test_robots_by_name(fleet: Fleet) -> None:
    assert len(fleet) == 3
    assert list(fleet) == ["a", "b", "c"] == list(fleet.names)
    assert "a" in fleet
    assert "z" not in fleet
    assert all(isinstance(fleet[name], Robot) for name in fleet)
    assert fleet["a"] is not fleet["b"]
    assert fleet.name_of(fleet["b"]) == "b"
    assert fleet.states() == dict.fromkeys("abc", LinkState.UP)
    with pytest.raises(KeyError):
        fleet["z"]


async def test_one_failure_does_not_block_the_others() -> None:
    dead = closed_port()
    with anyio.fail_after(WAIT):
        async with connect_fleet(
            {"up": SIM, "down": dead}, retry_initial=0.05, connect_timeout=2
        ) as fleet:
            assert fleet.state("up") is LinkState.UP
            assert fleet.state("down") is LinkState.LOST
            assert fleet.get("down") is None
            assert fleet.error("down") is not None
            with pytest.raises(NotReady, match="'down' is not connected"):
                fleet["down"]
            await fleet["up"].wait_until(lambda s: True, timeout=WAIT)


async def test_a_robot_that_comes_up_later_joins() -> None:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    with anyio.fail_after(WAIT):
        async with (
            Simulator.from_url("sim://?speed=20") as simulator,
            connect_fleet(
                {"late": f"socket://127.0.0.1:{port}"}, retry_initial=0.02, retry_max=0.05
            ) as fleet,
        ):
            assert fleet.state("late") is LinkState.LOST
            stream = fleet.statuses()
            server = await simulator.serve_tcp(port=port)
            try:
                name, status = await stream.__anext__()
            finally:
                stream.close()
                server.close()
            assert name == "late"
            assert status.time_stamp is not None
            assert fleet.state("late") is LinkState.UP


class _OneFrameRobot(asyncio.Protocol):
    """Sends one status frame on connect, then stays silent (a robot that hung)."""

    transports: ClassVar[list[asyncio.Transport]] = []

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        assert isinstance(transport, asyncio.Transport)
        self.transports.append(transport)
        transport.write(status_frame(1))


async def test_stale_then_lost_state_and_events() -> None:
    loop = asyncio.get_running_loop()
    server = await loop.create_server(_OneFrameRobot, "127.0.0.1", 0)
    port = server.sockets[0].getsockname()[1]
    url = f"socket://127.0.0.1:{port}"
    try:
        with anyio.fail_after(WAIT):
            async with connect_fleet(
                {"r": url, "s": SIM}, stale_timeout=0.1, stale_reconnect=None,
                reconnect_initial=30, reconnect_max=30,
                # A loaded machine must not make the healthy robot look stale.
                robot_options={"s": {"stale_timeout": 30.0}},
            ) as fleet:  # fmt: skip
                events = fleet.events()
                name, event = await events.__anext__()
                assert (name, type(event)) == ("r", ev.LinkStaleEvent)
                assert fleet.state("r") is LinkState.STALE
                assert fleet.state("s") is LinkState.UP
                for transport in _OneFrameRobot.transports:
                    transport.close()
                name, event = await events.__anext__()
                assert (name, type(event)) == ("r", ev.ConnectionLostEvent)
                assert fleet.state("r") is LinkState.LOST
                events.close()
    finally:
        server.close()
        _OneFrameRobot.transports.clear()


async def test_a_dropped_robot_reconnects_and_stays_in_the_merged_stream() -> None:
    # Every connection of this simulator drops after one simulated second (50 ms real).
    async with Simulator.from_url("sim://?speed=20&disconnect_after=1") as simulator:
        server = await simulator.serve_tcp()
        url = f"socket://127.0.0.1:{server.sockets[0].getsockname()[1]}"
        try:
            with anyio.fail_after(WAIT):
                async with connect_fleet(
                    {"r": url}, reconnect_initial=0.01, reconnect_max=0.05
                ) as fleet:
                    events = fleet.events()
                    seen: list[type] = []
                    while ev.ConnectionRestored not in seen:
                        name, event = await events.__anext__()
                        assert name == "r"
                        seen.append(type(event))
                    assert ev.ConnectionLostEvent in seen
                    assert fleet["r"].link.reconnects >= 1
                    stream = fleet.statuses()
                    await stream.__anext__()  # the latest
                    name, status = await stream.__anext__()  # a newer one, after the reconnect
                    assert name == "r"
                    assert status is fleet["r"].status
                    events.close()
                    stream.close()
        finally:
            server.close()


async def test_each_returns_results_and_errors(fleet: Fleet) -> None:
    async def power(robot: Robot) -> float:
        assert robot.status is not None
        return float(robot.status.power or 0)

    results = await fleet.each(power)
    assert set(results) == {"a", "b", "c"}
    assert all(isinstance(r, FleetResult) and r.ok for r in results.values())

    async def fail_on_b(robot: Robot) -> int:
        if robot is fleet["b"]:
            raise RuntimeError("b failed")
        return 1

    results2 = await fleet.each(fail_on_b, names=["a", "b"])
    assert list(results2) == ["a", "b"]
    assert results2["a"].value == 1
    assert isinstance(results2["b"].error, RuntimeError)
    with pytest.raises(InvalidArgument, match="'nope'"):
        await fleet.each(fail_on_b, names=["nope"])


async def test_each_real_operation(fleet: Fleet) -> None:
    results = await fleet.each(lambda robot: robot.start_navigation(), names=["a", "c"])
    assert all(result.ok for result in results.values()), results
    status = fleet["a"].status
    assert status is not None
    assert status.navigating


@pytest.mark.parametrize("how", WAYS)
async def test_each_cancelled_leaves_nothing_running(fleet: Fleet, how: str) -> None:
    started: list[str] = []

    async def forever(robot: Robot) -> None:
        started.append(robot.link.layout or "")
        await asyncio.Event().wait()

    await stop_waiting(how, lambda: fleet.each(forever), 0.05)
    assert len(started) == 3


async def test_invalid_arguments_before_anything_opens() -> None:
    with pytest.raises(InvalidArgument, match="non-empty mapping"):
        connect_fleet({})
    with pytest.raises(InvalidArgument, match="robot 'a'"):
        connect_fleet({"a": ""})
    with pytest.raises(InvalidArgument, match="'ghost'"):
        connect_fleet({"a": SIM}, robot_options={"ghost": {}})
    with pytest.raises(InvalidArgument, match="retry_initial"):
        connect_fleet({"a": SIM}, retry_initial=0)
    with pytest.raises(InvalidArgument, match="connect_concurrency"):
        connect_fleet({"a": SIM}, connect_concurrency=0)


async def test_bad_robot_option_is_raised_not_retried() -> None:
    options = {"b": {"map_targets": -1}}
    with anyio.fail_after(WAIT), pytest.raises(InvalidArgument, match="map_targets"):
        async with connect_fleet({"a": SIM, "b": SIM}, robot_options=options):
            pass  # pragma: no cover


async def test_per_robot_options(fleet: Fleet) -> None:
    async with connect_fleet({"a": SIM, "b": SIM}, robot_options={"b": {"map_targets": 2}}) as f:
        assert f["b"].map_targets == 2
        assert f["a"].map_targets == 6  # sim:// knows its map


@pytest.mark.parametrize("how", WAYS)
async def test_entering_cancelled_closes_everything(how: str) -> None:
    # A robot that never answers keeps the fleet's first tries waiting.
    with socket.socket() as listener:
        listener.bind(("127.0.0.1", 0))
        listener.listen()
        port = listener.getsockname()[1]
        ports = {"a": SIM, "silent": f"socket://127.0.0.1:{port}"}

        async def enter() -> None:
            async with connect_fleet(ports, first_status_timeout=30):
                pytest.fail("entered")  # pragma: no cover

        await stop_waiting(how, enter, 0.3)


async def test_close_ends_merged_streams_and_is_idempotent() -> None:
    async with connect_fleet({"a": SIM}) as fleet:
        statuses = fleet.statuses()
        events = fleet.events()
        robot = fleet["a"]
        await fleet.close()
        assert fleet.closed
        assert robot.closed
        assert fleet.state("a") is LinkState.CLOSED  # its link is closed, not lost
        with anyio.fail_after(WAIT):
            remaining = [item async for item in statuses]
            assert len(remaining) <= 1  # the latest status, if not taken yet
            assert [item async for item in events] == []
    await fleet.close()
