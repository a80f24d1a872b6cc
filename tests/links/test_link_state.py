"""One link state, kept by the link: its walk through an outage, how it is followed, who shows it.

The sequences run over real TCP: a fake device that pushes frames on demand, or the simulator
behind a relay that can go silent without closing (a hung robot process).
"""

from __future__ import annotations

import asyncio
import gc
import io
import re
import weakref
from collections.abc import AsyncIterator, Awaitable, Callable
from contextlib import asynccontextmanager
from typing import Any

import anyio
import pytest
from rich.console import Console

import galileo_async as galileo
from galileo_async import LinkState, Robot, connect_fleet
from galileo_async.cli.fleet_view import fleet_rows
from galileo_async.cli.render import dashboard, link_dict
from galileo_async.errors import ConnectionLost, GalileoTimeout, InvalidArgument
from galileo_async.links import open_link
from galileo_async.sim import Simulator
from galileo_async.state import StatusStore
from galileo_async.transports import Link, LinkStateStream
from tests.support.cancel_ways import WAYS, stop_waiting
from tests.support.fake_device import FakeDevice, make_status
from tests.support.vda5050_support import (
    Broker,
    Master,
    broker_fixture,  # noqa: F401 (the broker fixture)
    error_types,
)
from tests.vda5050.test_vda5050_links import FreezingProxy
from tests.vda5050.test_vda5050_vehicle import vehicle_on

STEP = 5.0
#: Stale after 0.4 s of silence (a loaded machine may delay a frame 0.2 s), given up after
#: 1 s; reopened within 0.1 s.
OPTIONS: dict[str, Any] = {
    "stale_timeout": 0.4, "stale_reconnect": 2.5, "reconnect_initial": 0.02,
    "reconnect_max": 0.1,
}  # fmt: skip

Check = Callable[[LinkState], Awaitable[None]]


async def next_state(states: LinkStateStream) -> LinkState:
    return await asyncio.wait_for(anext(states), STEP)


async def test_a_link_walks_connecting_up_stale_up_lost_up_closed(
    device: FakeDevice, links: list[Link]
) -> None:
    link = open_link(
        device.url, StatusStore(), stale_timeout=0.5, stale_reconnect=10.0,
        reconnect_initial=0.02, reconnect_max=0.1,
    )  # fmt: skip
    links.append(link)
    states = link.states()
    heard: list[LinkState] = []
    link.add_state_listener(heard.append)
    await link.open()
    assert await next_state(states) is LinkState.CONNECTING
    await device.wait_for(lambda: len(device.clients) == 1)
    device.push()
    assert await next_state(states) is LinkState.UP
    assert await next_state(states) is LinkState.STALE  # silent for stale_timeout
    assert link.stats.state is LinkState.STALE
    device.push()
    assert await next_state(states) is LinkState.UP
    await device.drop_clients()
    assert await next_state(states) is LinkState.LOST
    await device.wait_for(lambda: device.connections == 2)  # reopened, nobody answers
    device.push()
    # The reopen alone changed nothing: the frame is what ends the outage.
    assert await next_state(states) is LinkState.UP
    assert link.stats.reconnects == 1
    await link.close()
    assert await next_state(states) is LinkState.CLOSED
    with pytest.raises(StopAsyncIteration):
        await next_state(states)
    assert heard == [
        LinkState.UP, LinkState.STALE, LinkState.UP, LinkState.LOST, LinkState.UP,
        LinkState.CLOSED,
    ]  # fmt: skip
    assert link.state is link.stats.state is LinkState.CLOSED


@asynccontextmanager
async def relayed_simulator() -> AsyncIterator[tuple[str, FreezingProxy]]:
    """A simulator behind a FreezingProxy: the URL to connect to, and the proxy."""
    async with Simulator(speed=3) as sim:
        server = await sim.serve_tcp()
        proxy = FreezingProxy(server.sockets[0].getsockname()[1])
        try:
            yield f"socket://127.0.0.1:{await proxy.start()}", proxy
        finally:
            await proxy.close()


async def walk(robot: Robot, proxy: FreezingProxy, check: Check, close: Callable[[], Any]) -> None:
    """Take ``robot`` through an outage and its close; ``check`` each state as it comes."""
    states = robot.link_states()
    seen: list[LinkState] = []

    async def expect(state: LinkState) -> None:
        got = await next_state(states)
        seen.append(got)
        assert got is state, seen
        await check(state)

    await expect(LinkState.UP)
    proxy.frozen = True
    await expect(LinkState.STALE)
    proxy.frozen = False
    await expect(LinkState.UP)
    proxy.frozen = True
    await expect(LinkState.STALE)
    await expect(LinkState.LOST)  # given up after stale_reconnect × stale_timeout
    await proxy.wait_accepted(2)  # reopened, still silent: still lost
    await check(LinkState.LOST)
    proxy.frozen = False
    await expect(LinkState.UP)
    await close()
    await expect(LinkState.CLOSED)
    with pytest.raises(StopAsyncIteration):
        await next_state(states)


async def test_the_robot_shows_the_links_state_and_follows_it() -> None:
    async with relayed_simulator() as (url, proxy):
        robot = await galileo.connect(url, **OPTIONS)
        try:

            async def check(state: LinkState) -> None:
                assert robot.link_state is robot.link.state is state

            await walk(robot, proxy, check, robot.close)
        finally:
            await robot.close()


async def test_the_fleet_shows_the_links_state() -> None:
    async with relayed_simulator() as (url, proxy), connect_fleet({"r": url}, **OPTIONS) as fleet:
        robot = fleet["r"]

        async def check(state: LinkState) -> None:
            assert fleet.state("r") is state
            assert fleet.states() == {"r": state}
            [row] = fleet_rows(fleet, {}, {})  # the `galileo fleet` table
            assert row.state is state

        await walk(robot, proxy, check, fleet.close)


def monitor_link_row(robot: Robot) -> str:
    """What the monitor's link panel says in its "link" row."""
    console = Console(file=io.StringIO(), record=True, width=200, color_system=None)
    console.print(dashboard(robot.status, robot.link, [], url="socket://robot"))
    [state] = re.findall(r"│ link +(\w+) │", console.export_text())
    return str(state)


async def test_the_monitor_shows_the_links_state() -> None:
    async with relayed_simulator() as (url, proxy):
        robot = await galileo.connect(url, **OPTIONS)
        try:

            async def check(state: LinkState) -> None:
                assert link_dict(robot.link)["state"] == state.value  # `galileo status --json`
                if robot.status is not None:
                    assert monitor_link_row(robot) == state.value

            await walk(robot, proxy, check, robot.close)
        finally:
            await robot.close()


async def test_wait_link_returns_the_state_times_out_and_ends_with_the_link() -> None:
    async with relayed_simulator() as (url, proxy):
        robot = await galileo.connect(url, **OPTIONS)
        try:
            assert await robot.wait_link(LinkState.UP) is LinkState.UP  # at once
            with pytest.raises(InvalidArgument):
                await robot.wait_link()
            with pytest.raises(InvalidArgument):
                await robot.wait_link("up")  # type: ignore[arg-type]
            with pytest.raises(GalileoTimeout, match="lost"):
                await robot.wait_link(LinkState.LOST, timeout=0.05)
            proxy.frozen = True
            assert await robot.wait_link(LinkState.STALE, LinkState.LOST, timeout=STEP) is (
                LinkState.STALE
            )
            proxy.frozen = False
            assert await robot.wait_link(LinkState.UP, timeout=STEP) is LinkState.UP
            waiting = asyncio.ensure_future(robot.wait_link(LinkState.LOST, timeout=None))
            closing = asyncio.ensure_future(robot.wait_link(LinkState.CLOSED, timeout=None))
            await asyncio.sleep(0)
            await robot.close()
            with pytest.raises(ConnectionLost):
                await waiting
            assert await closing is LinkState.CLOSED
            with pytest.raises(ConnectionLost):
                await robot.wait_link(LinkState.UP)
        finally:
            await robot.close()


@pytest.mark.parametrize("how", WAYS)
async def test_following_stops_on_every_cancellation_route(how: str) -> None:
    async with relayed_simulator() as (url, _proxy):
        robot = await galileo.connect(url, **OPTIONS)
        try:
            streams: list[weakref.ref[LinkStateStream]] = []

            async def follow() -> None:
                states = robot.link_states()
                streams.append(weakref.ref(states))
                async for _state in states:
                    pass

            await stop_waiting(how, follow, 0.1)
            await stop_waiting(how, lambda: robot.wait_link(LinkState.LOST, timeout=None), 0.1)
            gc.collect()
            assert [ref() for ref in streams] == [None]  # nothing keeps the dropped iterator
            # Following goes on as before.
            assert await robot.wait_link(LinkState.UP) is LinkState.UP
            states = robot.link_states()
            assert await next_state(states) is LinkState.UP
            await robot.close()
            rest = [state async for state in states]  # ends after CLOSED
            # A loaded machine may let the short stale_timeout pass (and frames come again)
            # before the close: whatever came first, the stream ends with CLOSED.
            assert rest[-1] is LinkState.CLOSED, rest
            assert set(rest[:-1]) <= {LinkState.STALE, LinkState.UP}, rest
        finally:
            await robot.close()


async def test_a_link_state_stream_of_a_closed_link_gives_closed_and_ends() -> None:
    robot = await galileo.connect("sim://?speed=20")
    await robot.close()
    assert robot.link_state is LinkState.CLOSED
    with anyio.fail_after(STEP):
        assert [state async for state in robot.link_states()] == [LinkState.CLOSED]


async def test_a_store_calls_any_number_of_listeners_and_one_failing_stops_none() -> None:
    store = StatusStore()
    first: list[int] = []
    second: list[int] = []
    events: list[str] = []

    def broken(_status: Any) -> None:
        raise RuntimeError("a broken listener")

    def record_first(status: Any) -> None:
        first.append(status.time_stamp)

    store.add_update_listener(record_first)
    store.add_update_listener(broken)
    store.add_update_listener(lambda status: second.append(status.time_stamp))
    store.add_event_listener(lambda event: events.append(event.name))
    store.add_event_listener(broken)
    store.add_event_listener(lambda event: events.append(event.name))
    store.update(make_status(time_stamp=1, nav_status=0))
    store.update(make_status(time_stamp=2, nav_status=1))
    assert first == second == [1, 2]
    assert events == ["NavigationOpened"] * 2
    store.remove_update_listener(record_first)
    store.update(make_status(time_stamp=3, nav_status=1))
    assert first == [1, 2]  # removed: not called again; the others stay
    assert second == [1, 2, 3]


async def test_a_fleet_robot_keeps_the_fleets_feed_and_its_users_listeners() -> None:
    async with relayed_simulator() as (url, _proxy), connect_fleet({"r": url}, **OPTIONS) as fleet:
        robot = fleet["r"]
        mine: list[int] = []
        states = robot.link_states()
        robot.add_update_listener(lambda status: mine.append(status.time_stamp))
        merged = fleet.statuses()
        with anyio.fail_after(STEP):
            for _ in range(3):  # the fleet's merged stream still moves
                await anext(merged)
            while len(mine) < 3:
                await anext(merged)
        assert mine == sorted(mine)
        merged.close()
        await fleet.close()
        assert [state async for state in states] == [LinkState.UP, LinkState.CLOSED]


async def test_a_vehicle_started_on_a_lost_link_reports_it_at_once(broker: Broker) -> None:
    async with relayed_simulator() as (url, proxy):
        robot = await galileo.connect(url, **OPTIONS)
        try:
            proxy.frozen = True
            await robot.wait_link(LinkState.LOST, timeout=STEP)
            # Its outage was reported before the vehicle ran: the state says so anyway.
            async with Master.connected(broker) as master, vehicle_on(broker, robot):
                lost = await master.next_state(lambda s: "robotLinkLost" in error_types(s))
                [fatal] = [e for e in lost["errors"] if e["errorType"] == "robotLinkLost"]
                assert {"referenceKey": "link", "referenceValue": "ConnectionLost"} in (
                    fatal["errorReferences"]
                )
                proxy.frozen = False
                await master.next_state(lambda s: "robotLinkLost" not in error_types(s))
                assert robot.link_state is LinkState.UP
        finally:
            await robot.close()
