"""The real serial connector over a pseudo-terminal pair (Linux)."""

from __future__ import annotations

import asyncio
import contextlib
import os
import sys
from collections.abc import AsyncIterator, Iterator

import pytest
import serial

from galileo_async import events as ev
from galileo_async.errors import ConnectionLost, GalileoConnectionError
from galileo_async.links import open_link
from galileo_async.protocol import CommandDecoder, Goto, StopPatrol, encode
from galileo_async.state import StatusStore
from galileo_async.transports import StreamChannel
from galileo_async.transports.connectors import serial_backend, translate_errors
from tests.support.fake_device import status_frame

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="pty is Linux-only")

STEP = 2.0


class PtyDevice:
    """The robot's end of a pty: the link opens the slave path as its serial port."""

    def __init__(self) -> None:
        self.master, self._slave = os.openpty()
        self.path = os.ttyname(self._slave)
        os.set_blocking(self.master, False)
        self.received = bytearray()
        self._changed = asyncio.Event()
        asyncio.get_running_loop().add_reader(self.master, self._readable)

    def _readable(self) -> None:
        try:
            self.received += os.read(self.master, 4096)
        except OSError:  # EIO once no process holds the slave open
            asyncio.get_running_loop().remove_reader(self.master)
        self._changed.set()

    def write(self, data: bytes) -> None:
        os.write(self.master, data)

    async def wait_received(self, size: int) -> bytes:
        async def until() -> None:
            while len(self.received) < size:
                self._changed.clear()
                await self._changed.wait()

        await asyncio.wait_for(until(), STEP)
        return bytes(self.received)

    def close(self) -> None:
        asyncio.get_running_loop().remove_reader(self.master)
        for fd in (self.master, self._slave):
            with contextlib.suppress(OSError):
                os.close(fd)


@pytest.fixture
async def pty() -> AsyncIterator[PtyDevice]:
    device = PtyDevice()
    yield device
    device.close()


@pytest.fixture(params=["serial_asyncio_fast", "serial_asyncio"])
def backend(request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch) -> Iterator[str]:
    if request.param == "serial_asyncio":  # hide the fast backend: the fallback must work too
        monkeypatch.setitem(sys.modules, "serial_asyncio_fast", None)
    return request.param


async def test_status_and_commands_over_a_pty(pty: PtyDevice, backend: str) -> None:
    assert serial_backend().__name__ == backend
    store = StatusStore()
    link = open_link(pty.path, store, baudrate=115200, stale_timeout=5.0)
    assert isinstance(link.channel, StreamChannel)
    await link.open()
    try:
        pty.write(status_frame(1, nav_status=1) + status_frame(2, nav_status=1)[:40])
        pty.write(status_frame(2, nav_status=1)[40:])
        status = await store.wait_until(lambda s: s.time_stamp == 2, timeout=STEP)
        assert status.navigating
        assert link.stats.frames == 2
        assert link.stats.bytes_received == 2 * 89
        await link.send(Goto(3))
        await link.send(StopPatrol())
        data = await pty.wait_received(len(encode(Goto(3))) + len(encode(StopPatrol())))
        assert data == encode(Goto(3)) + encode(StopPatrol())
        assert CommandDecoder().feed(data) == [Goto(3), StopPatrol()]
    finally:
        await asyncio.wait_for(link.close(), STEP)


async def test_unplugging_the_device_fails_waiters(pty: PtyDevice) -> None:
    store = StatusStore()
    link = open_link(pty.path, store, reconnect=False, stale_timeout=5.0)
    await link.open()
    events = store.events()
    try:
        pty.write(status_frame(1))
        await store.wait_until(lambda s: s.time_stamp == 1, timeout=STEP)
        waiter = asyncio.create_task(store.wait_until(lambda s: False, timeout=60))
        await asyncio.sleep(0)
        pty.close()  # the adapter disappears: reads on the port fail
        with pytest.raises(ConnectionLost):
            await asyncio.wait_for(waiter, STEP)
        assert isinstance(await asyncio.wait_for(anext(events), STEP), ev.ConnectionLostEvent)
    finally:
        await asyncio.wait_for(link.close(), STEP)


async def test_missing_device_is_a_connection_error(backend: str) -> None:
    link = open_link("/dev/galileo-does-not-exist", StatusStore())
    with pytest.raises(GalileoConnectionError) as info:
        await link.open()
    assert isinstance(info.value.__cause__, OSError)  # serial.SerialException
    assert "galileo-does-not-exist" in str(info.value)
    await link.close()


def test_translate_errors_maps_foreign_exceptions_only() -> None:
    for foreign in (serial.SerialException("gone"), OSError(5, "EIO"), TimeoutError()):
        with (
            pytest.raises(GalileoConnectionError, match="opening") as info,
            translate_errors("opening"),
        ):
            raise foreign
        assert info.value.__cause__ is foreign
    own = ConnectionLost("ours")
    with pytest.raises(ConnectionLost) as caught, translate_errors("opening"):
        raise own
    assert caught.value is own
    with pytest.raises(KeyError), translate_errors("opening"):  # bugs are not connection errors
        raise KeyError("bug")
