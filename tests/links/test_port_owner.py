"""One serial port, one owner: a second opener gets PortBusy at once; the owner is unaffected.

The simulator serves a pty, as a USB adapter gives /dev/ttyUSB0. Also here: a drop while
connect() waits for the first frame names the transport's reason, and ``galileo record``
fails when its link ends early.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import os
import sys
import time
from collections.abc import AsyncIterator, Iterator
from pathlib import Path

import pytest

import galileo_async as galileo
from galileo_async import ConnectionLost, PortBusy
from galileo_async.cli import ExitCode
from galileo_async.sim import Simulator
from galileo_async.transports import DEFAULT_BAUDRATE, serial_connector
from tests.support.fake_device import FakeDevice

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="pty is Linux-only")

WAIT = 15.0
#: PortBusy comes from the open itself, well within this.
AT_ONCE = 1.0
GALILEO = [sys.executable, "-m", "galileo_async"]


@pytest.fixture(params=["serial_asyncio_fast", "serial_asyncio"])
def backend(request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch) -> Iterator[str]:
    if request.param == "serial_asyncio":  # hide the fast backend: the fallback must honour it
        monkeypatch.setitem(sys.modules, "serial_asyncio_fast", None)
    return request.param


@pytest.fixture
async def pty_sim() -> AsyncIterator[str]:
    """The path of a pty the simulator serves (its frames flow from the start)."""
    async with Simulator(speed=20) as sim:
        yield sim.open_pty()


async def frames_keep_coming(robot: galileo.Robot, count: int = 10) -> None:
    until = robot.link.frames + count
    await robot.wait_until(lambda _s: robot.link.frames >= until, timeout=WAIT)


async def test_a_second_connect_gets_port_busy_at_once(pty_sim: str, backend: str) -> None:
    async with galileo.connect(pty_sim) as first:
        await frames_keep_coming(first)
        started = time.monotonic()
        with pytest.raises(PortBusy) as info:
            await galileo.connect(pty_sim)  # reconnect on (the default): it must not hide this
        assert time.monotonic() - started < AT_ONCE
        assert info.value.port == pty_sim
        assert pty_sim in str(info.value)
        assert isinstance(info.value, galileo.GalileoConnectionError)
        await frames_keep_coming(first)
        assert first.link.connected
        assert first.link.reconnects == 0
    async with galileo.connect(pty_sim) as again:  # the owner closed: the port is free again
        await frames_keep_coming(again)


async def test_a_raw_open_of_an_owned_port_is_busy_too(pty_sim: str) -> None:
    loop = asyncio.get_running_loop()
    async with galileo.connect(pty_sim) as first:
        with pytest.raises(PortBusy):
            await serial_connector(pty_sim)(loop, asyncio.Protocol)
        await frames_keep_coming(first)
        # Sharing is still possible when asked for.
        shared = serial_connector(pty_sim, baudrate=DEFAULT_BAUDRATE, exclusive=False)
        transport, _ = await shared(loop, asyncio.Protocol)
        transport.close()


async def run_cli(*args: str) -> tuple[int, str, str]:
    env = {key: value for key, value in os.environ.items() if key != "GALILEO_PORT"}
    process = await asyncio.create_subprocess_exec(
        *GALILEO,
        *args,
        stdout=asyncio.subprocess.PIPE,
        stderr=asyncio.subprocess.PIPE,
        env=env | {"COLUMNS": "200"},
    )
    out, err = await asyncio.wait_for(process.communicate(), WAIT)
    assert process.returncode is not None
    return process.returncode, out.decode(), err.decode()


async def test_the_cli_says_the_port_is_busy_and_exits_with_its_code(
    pty_sim: str, tmp_path: Path
) -> None:
    async with galileo.connect(pty_sim) as first:
        code, _out, err = await run_cli("--port", pty_sim, "status")
        assert code == ExitCode.PORT_BUSY == 9, err
        assert "PortBusy" in err
        assert pty_sim in err
        code, _out, err = await run_cli("--port", pty_sim, "record", str(tmp_path / "capture"))
        assert code == ExitCode.PORT_BUSY, err
        assert "PortBusy" in err
        await frames_keep_coming(first)


async def test_record_fails_when_the_link_ends_before_the_duration(
    device: FakeDevice, tmp_path: Path
) -> None:
    capture = tmp_path / "capture"
    process = asyncio.create_task(
        run_cli("--port", device.url, "record", str(capture), "--duration", "30")
    )
    await device.wait_for(lambda: len(device.clients) == 1, timeout=WAIT)
    device.push()
    await device.drop_clients()  # the link ends 29 s early
    code, out, err = await process
    assert code == ExitCode.CONNECTION, (out, err)
    assert "recorded 89 bytes" in out
    assert "before the requested 30" in err


class _Opened(logging.Handler):
    """Sets ``event`` when the serial connector logs that it opened the port."""

    def __init__(self, event: asyncio.Event) -> None:
        super().__init__(logging.DEBUG)
        self.event = event

    def emit(self, record: logging.LogRecord) -> None:
        if record.getMessage().startswith("opened "):
            self.event.set()


@contextlib.contextmanager
def port_opened(event: asyncio.Event) -> Iterator[None]:
    logger = logging.getLogger("galileo_async.transports.connectors")
    handler, level = _Opened(event), logger.level
    logger.addHandler(handler)
    logger.setLevel(logging.DEBUG)
    try:
        yield
    finally:
        logger.removeHandler(handler)
        logger.setLevel(level)


async def open_robot(url: str, **options: object) -> galileo.Robot:
    return await galileo.connect(url, **options)


@pytest.mark.parametrize("reconnect", [False, True])
async def test_a_drop_while_connect_waits_for_the_first_frame_names_its_reason(
    reconnect: bool,
) -> None:
    master, slave = os.openpty()  # a device that never sends, then is unplugged
    path = os.ttyname(slave)
    opened = asyncio.Event()
    # Reconnecting, connect() waits out its timeout (the port is gone), then says why.
    options = {"reconnect": reconnect, "first_status_timeout": 0.5 if reconnect else WAIT}
    expected = galileo.GalileoConnectionError if reconnect else ConnectionLost
    try:
        with port_opened(opened):
            connecting = asyncio.create_task(open_robot(path, **options))
            await asyncio.wait_for(opened.wait(), WAIT)
            os.close(master)
            os.close(slave)
            with pytest.raises(expected) as info:
                await asyncio.wait_for(connecting, WAIT)
    finally:
        for fd in (master, slave):
            with contextlib.suppress(OSError):
                os.close(fd)
    message = str(info.value)
    assert "store is closed" not in message
    assert "device reports readiness to read but returned no data" in message
    assert path in message
