"""http:// connected, closed and connected again to one HTTP face; timeouts that say their clock."""

from __future__ import annotations

import asyncio
import contextlib
import socket
from collections.abc import Iterator

import pytest

import galileo_async as galileo
from galileo_async import GalileoConnectionError, HttpTimeout
from galileo_async.http import HttpApi
from galileo_async.options import FIRST_STATUS_TIMEOUT
from galileo_async.sim import Simulator
from galileo_async.testing import VirtualClock
from tests.cli.test_cli_served import HttpServedSim

pytestmark = pytest.mark.timeout(120)

#: Connections one after another to one face.
RUNS = 50
#: A timeout no run of these tests waits out in real time, seconds.
HOUR = 3600.0
#: What a timeout's message adds when the loop's clock ran ahead of the real one.
RAN_AHEAD = "by the event loop's clock, which ran ahead"


@pytest.fixture
def served() -> Iterator[HttpServedSim]:
    sim = HttpServedSim(speed=5.0)
    try:
        yield sim
    finally:
        sim.close()


async def test_connect_close_and_connect_again_in_one_loop() -> None:
    async with Simulator(speed=5.0) as sim:
        face = await sim.serve_http()
        url = f"http://127.0.0.1:{face.address[1]}?ws_port={face.ws_address[1]}"
        for run in range(RUNS):
            async with galileo.connect(url, reconnect=False) as robot:
                assert robot.status is not None, run
            await asyncio.sleep(0)
        assert not face.sockets  # every client's WebSocket closed with its robot


def test_connect_in_one_event_loop_after_another(served: HttpServedSim) -> None:
    # As the CLI does: asyncio.run per connection, against a face that outlives them all.
    async def once() -> tuple[int, str]:
        async with galileo.connect(served.url, reconnect=False) as robot:
            assert robot.http is not None
            info = await robot.http.info()
            return robot.link.reconnects, info.version

    for run in range(RUNS):
        assert asyncio.run(once()) == (0, "5.1.0"), run


@contextlib.contextmanager
def deaf_port() -> Iterator[int]:
    """A port on 127.0.0.1 whose connections the kernel accepts and nobody ever reads."""
    with socket.socket() as listener:
        listener.bind(("127.0.0.1", 0))
        listener.listen(8)
        port: int = listener.getsockname()[1]
        yield port


async def test_a_rest_timeout_on_a_virtual_clock_says_how_little_real_time_passed() -> None:
    # The server is outside the loop: the virtual clock jumps to the timeout at once, and
    # the message says the hour passed by the loop's clock only.
    with deaf_port() as port:
        api = HttpApi(f"http://127.0.0.1:{port}", timeout=HOUR)
        clock = VirtualClock.install()
        try:
            with pytest.raises(HttpTimeout) as info:
                await api.call("GET", "/system/info")
        finally:
            clock.release()
            await api.close()
    message = str(info.value)
    assert f"no answer within {HOUR} s from http://127.0.0.1:{port} (request_timeout)" in message
    assert RAN_AHEAD in message
    assert "s of real time passed" in message


async def test_a_websocket_timeout_on_a_virtual_clock_says_how_little_real_time_passed() -> None:
    with deaf_port() as port:
        url = f"http://127.0.0.1:{port}?ws_port={port}"
        clock = VirtualClock.install()
        try:
            with pytest.raises(HttpTimeout) as info:
                await galileo.connect(url, reconnect=False, connect_timeout=HOUR)
        finally:
            clock.release()
    message = str(info.value)
    assert f"no answer within {HOUR} s (connect_timeout) ({RAN_AHEAD}" in message


async def test_a_first_status_timeout_on_a_virtual_clock_says_how_little_real_time_passed() -> None:
    with deaf_port() as port:
        url = f"socket://127.0.0.1:{port}"
        clock = VirtualClock.install()
        try:
            with pytest.raises(GalileoConnectionError) as info:
                await galileo.connect(url, reconnect=False)
        finally:
            clock.release()
    message = str(info.value)
    within = f"no valid status frame arrived within {FIRST_STATUS_TIMEOUT} s ({RAN_AHEAD}"
    assert within in message
