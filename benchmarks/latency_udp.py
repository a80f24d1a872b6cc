"""Latency over ``udp://``: the same two paths as latency.py, on a device-side UDP endpoint.

The device end is a datagram endpoint on 127.0.0.1 in the same process and loop, playing
the robot's port 20001: it answers the registration datagram with a first status, then
sends a 48-byte status frame on demand to the last sender. The UDP frame has no frame
counter, so frame ``k`` carries ``target_num_id = k``.

* **status → waiter**: t0 just before ``sendto``; t1 when ``await robot.wait_until(lambda s:
  s.target_num_id == k)`` returns. Baseline: a bare ``DatagramProtocol`` that checks the
  header, unpacks the frame and resolves a future a task awaits.
* **command → datagram**: t0 just before ``await robot.forward(20)``; t1 when the device's
  ``datagram_received`` gets it. Baseline: ``transport.sendto(encode(Forward(20)))``.
"""

from __future__ import annotations

import asyncio
import time
from collections.abc import Callable
from typing import Any

import galileo_async
from galileo_async import GalileoStatus, StatusLayout
from galileo_async.protocol import HEADER, UDP_LAYOUTS, encode, encode_status
from galileo_async.protocol.commands import Forward

from .latency_loops import Arrivals, bare_status, driver_status, timed_commands

__all__ = ["REGISTRATION", "udp_command_latency", "udp_status_latency"]

#: The datagram a host sends to register for statuses (a firmware fact, docs/transports.md);
#: spelt out here so the benchmark runs against any tree of the package.
REGISTRATION = HEADER + b"\x00"

_UNPACK = UDP_LAYOUTS[StatusLayout.UDP_V2].struct.unpack_from
_TARGET_ID = 7  # x, y, reserved, power, flags, angle, target_status, target_num_id, …


def _frame(target_num_id: int) -> bytes:
    status = GalileoStatus(
        layout=StatusLayout.UDP_V2, nav_status=1, visual_status=1, power=24.0,
        target_num_id=target_num_id,
    )  # fmt: skip
    return encode_status(status)


class _Device(asyncio.DatagramProtocol):
    """The robot's port: a first status to whoever registers, timestamps of what arrives."""

    def __init__(self, on_datagram: Callable[[float], None]) -> None:
        self.transport: asyncio.DatagramTransport | None = None
        self.remote: Any = None
        self._on_datagram = on_datagram

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        self.transport = transport  # type: ignore[assignment]

    def datagram_received(self, data: bytes, addr: Any) -> None:
        when = time.perf_counter()
        self.remote = addr
        if data == REGISTRATION:
            assert self.transport is not None
            self.transport.sendto(_frame(1), addr)  # the host's connect waits for a status
        else:
            self._on_datagram(when)

    def send(self, frame: bytes) -> None:
        assert self.transport is not None
        self.transport.sendto(frame, self.remote)


class _Bare(asyncio.DatagramProtocol):
    """Baseline host: header check + unpack, then resolve the awaited future."""

    def __init__(self) -> None:
        self.waiting: tuple[int, asyncio.Future[None]] | None = None

    def datagram_received(self, data: bytes, addr: Any) -> None:
        if not data.startswith(HEADER) or self.waiting is None:
            return
        wanted, future = self.waiting
        if _UNPACK(data, 4)[_TARGET_ID] == wanted and not future.done():
            future.set_result(None)


async def _device(on_datagram: Callable[[float], None]) -> tuple[_Device, int]:
    loop = asyncio.get_running_loop()
    _, device = await loop.create_datagram_endpoint(
        lambda: _Device(on_datagram), local_addr=("127.0.0.1", 0)
    )
    assert device.transport is not None
    return device, int(device.transport.get_extra_info("sockname")[1])


async def udp_status_latency(samples: int) -> tuple[list[float], list[float], list[float]]:
    """Device sendto → waiter woken, driver and bare, and the driver's status ages, seconds."""
    device, port = await _device(lambda _when: None)
    loop = asyncio.get_running_loop()

    async def send(k: int) -> None:
        device.send(_frame(k))

    try:
        robot = await galileo_async.connect(f"udp://127.0.0.1:{port}", stale_timeout=None)
        try:
            driver, ages = await driver_status(robot, send, _target, samples)
        finally:
            await robot.close()
        transport, bare_host = await loop.create_datagram_endpoint(
            _Bare, remote_addr=("127.0.0.1", port)
        )

        async def wait(k: int) -> None:
            future: asyncio.Future[None] = loop.create_future()
            bare_host.waiting = (k, future)
            await future

        try:
            transport.sendto(REGISTRATION)
            await asyncio.sleep(0.01)  # the registration reaches the device first
            bare = await bare_status(send, wait, samples)
        finally:
            transport.close()
    finally:
        assert device.transport is not None
        device.transport.close()
    return driver, bare, ages


def _target(status: GalileoStatus) -> int | None:
    return status.target_num_id


async def udp_command_latency(samples: int) -> tuple[list[float], list[float]]:
    """robot.forward() call → datagram at the device, driver and bare, in seconds."""
    arrivals = Arrivals()
    device, port = await _device(arrivals)
    loop = asyncio.get_running_loop()
    try:
        robot = await galileo_async.connect(f"udp://127.0.0.1:{port}", stale_timeout=None)
        try:
            driver = await timed_commands(lambda: robot.forward(20), arrivals, samples)
        finally:
            await robot.close()
        transport, _ = await loop.create_datagram_endpoint(
            asyncio.DatagramProtocol, remote_addr=("127.0.0.1", port)
        )
        data = encode(Forward(20))

        async def write() -> None:
            transport.sendto(data)

        try:
            bare = await timed_commands(write, arrivals, samples)
        finally:
            transport.close()
    finally:
        assert device.transport is not None
        device.transport.close()
    return driver, bare
