"""Latency: device write → wait_until woken, and command call → bytes at the device.

The same two paths over ``udp://`` and ``http://`` are measured in the same run
(latency_udp.py, latency_http.py).

A device-side TCP server on 127.0.0.1 runs in the same process and event loop as the
host, so both sides read one clock (time.perf_counter) and every figure includes the
same loop turns for the driver and its baseline:

* **status → waiter**: the device writes frame ``k`` (t0 just before ``transport.write``);
  t1 is when ``await robot.wait_until(lambda s: s.time_stamp == k)`` returns in its task.
  Baseline: a bare ``asyncio.Protocol`` that finds the header, unpacks the frame and
  resolves a future the same kind of task awaits.
* **command → bytes**: t0 just before ``await robot.forward(20)``; t1 when the device's
  ``data_received`` gets the bytes. Baseline: ``transport.write(encode(Forward(20)))``.
  Samples are spaced beyond the driver's 10 ms command pacing, so pacing never delays one.
* **status age**: from the device's send (time.monotonic) to ``robot.link.last_frame_at``,
  set when the status reached the store; over socket://, udp:// and http:// in one run.

The loops are latency_loops.py's, shared by the three links.
"""

from __future__ import annotations

import asyncio
import time
from collections.abc import Callable
from typing import Any

import galileo_async
from galileo_async import GalileoStatus, StatusLayout
from galileo_async.protocol import HEADER, LAYOUTS, encode, encode_status
from galileo_async.protocol.commands import Forward

from .common import Row, percentile
from .latency_http import http_command_latency, http_status_latency
from .latency_loops import Arrivals, bare_status, driver_status, timed_commands
from .latency_udp import udp_command_latency, udp_status_latency

__all__ = ["run"]

_UNPACK = LAYOUTS[StatusLayout.V2].struct.unpack_from
_STAMP = LAYOUTS[StatusLayout.V2].fields.index("time_stamp")


def _frame(time_stamp: int) -> bytes:
    return encode_status(GalileoStatus(nav_status=1, visual_status=1, time_stamp=time_stamp))


class _Device(asyncio.Protocol):
    """The device end: writes frames on demand, timestamps what the host sends."""

    def __init__(self, on_bytes: Callable[[float], None]) -> None:
        self.transport: asyncio.WriteTransport | None = None
        self.connected: asyncio.Future[None] = asyncio.get_running_loop().create_future()
        self._on_bytes = on_bytes

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        assert isinstance(transport, asyncio.WriteTransport)
        self.transport = transport
        transport.write(_frame(1))  # the host's connect waits for a first status
        if not self.connected.done():
            self.connected.set_result(None)

    def data_received(self, data: bytes) -> None:
        self._on_bytes(time.perf_counter())


class _Bare(asyncio.Protocol):
    """Baseline host: header search + unpack, then resolve the awaited future."""

    def __init__(self) -> None:
        self.waiting: tuple[int, asyncio.Future[None]] | None = None
        self.transport: asyncio.WriteTransport | None = None

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        assert isinstance(transport, asyncio.WriteTransport)
        self.transport = transport

    def data_received(self, data: bytes) -> None:
        pos = data.find(HEADER)
        if pos < 0 or self.waiting is None:
            return
        stamp = _UNPACK(data, pos + 4)[_STAMP]
        wanted, future = self.waiting
        if stamp == wanted and not future.done():
            future.set_result(None)


async def _serve(on_bytes: Callable[[float], None]) -> tuple[asyncio.Server, list[_Device]]:
    devices: list[_Device] = []

    def factory() -> _Device:
        device = _Device(on_bytes)
        devices.append(device)
        return device

    server = await asyncio.get_running_loop().create_server(factory, "127.0.0.1", 0)
    return server, devices


async def _status_latency(samples: int) -> tuple[list[float], list[float], list[float]]:
    arrivals = Arrivals()
    server, devices = await _serve(arrivals)
    port = server.sockets[0].getsockname()[1]

    async def send(k: int) -> None:
        assert devices[-1].transport is not None
        devices[-1].transport.write(_frame(k))

    try:
        robot = await galileo_async.connect(f"socket://127.0.0.1:{port}", stale_timeout=None)
        try:
            driver, ages = await driver_status(robot, send, _time_stamp, samples)
        finally:
            await robot.close()
        loop = asyncio.get_running_loop()
        transport, bare_host = await loop.create_connection(_Bare, "127.0.0.1", port)

        async def wait(k: int) -> None:
            future: asyncio.Future[None] = loop.create_future()
            bare_host.waiting = (k, future)
            await future

        try:
            await devices[-1].connected
            bare = await bare_status(send, wait, samples)
        finally:
            transport.close()
    finally:
        server.close()
        await server.wait_closed()
    return driver, bare, ages


def _time_stamp(status: GalileoStatus) -> int | None:
    return status.time_stamp


async def _command_latency(samples: int) -> tuple[list[float], list[float]]:
    arrivals = Arrivals()
    server, _devices = await _serve(arrivals)
    port = server.sockets[0].getsockname()[1]
    try:
        robot = await galileo_async.connect(f"socket://127.0.0.1:{port}", stale_timeout=None)
        try:
            driver = await timed_commands(lambda: robot.forward(20), arrivals, samples)
        finally:
            await robot.close()
        loop = asyncio.get_running_loop()
        transport, _host = await loop.create_connection(asyncio.Protocol, "127.0.0.1", port)
        assert isinstance(transport, asyncio.WriteTransport)
        data = encode(Forward(20))

        async def write() -> None:
            transport.write(data)

        try:
            bare = await timed_commands(write, arrivals, samples)
        finally:
            transport.close()
    finally:
        server.close()
        await server.wait_closed()
    return driver, bare


def _rows(name: str, driver: list[float], bare: list[float]) -> list[Row]:
    ms = 1000
    added = percentile(driver, 99) - percentile(bare, 99)
    extra: dict[str, Any] = {"samples": len(driver), "added_p99_ms": added * ms}
    return [
        Row("latency", f"{name} p50", percentile(driver, 50) * ms, "ms",
            percentile(bare, 50) * ms, "bare protocol", "", None, extra),
        Row("latency", f"{name} p99", percentile(driver, 99) * ms, "ms",
            percentile(bare, 99) * ms, "bare protocol", "≤ bare + 1 ms", added <= 0.001, extra),
    ]  # fmt: skip


def _age_rows(name: str, ages: list[float], socket_ages: list[float] | None) -> list[Row]:
    ms = 1000
    base = "socket://" if socket_ages is not None else ""
    return [
        Row("latency", f"{name} status age (device send → store) p{q}",
            percentile(ages, q) * ms, "ms",
            None if socket_ages is None else percentile(socket_ages, q) * ms, base, "", None,
            {"samples": len(ages)})
        for q in (50, 99)
    ]  # fmt: skip


def run(*, quick: bool = False) -> list[Row]:
    """Measure both latencies and the status age, over socket://, udp:// and http://."""
    samples = 300 if quick else 2000
    status_driver, status_bare, ages = asyncio.run(_status_latency(samples))
    command_driver, command_bare = asyncio.run(_command_latency(samples // 4))
    udp_status_driver, udp_status_bare, udp_ages = asyncio.run(udp_status_latency(samples))
    udp_command_driver, udp_command_bare = asyncio.run(udp_command_latency(samples // 4))
    http_status_driver, http_status_bare, http_ages = asyncio.run(http_status_latency(samples))
    http_command_driver, http_command_bare = asyncio.run(http_command_latency(samples // 4))
    return [
        *_rows("status frame → wait_until woken", status_driver, status_bare),
        *_rows("robot.forward() call → bytes at device", command_driver, command_bare),
        *_rows("udp:// status datagram → wait_until woken", udp_status_driver, udp_status_bare),
        *_rows("udp:// robot.forward() → datagram at device", udp_command_driver, udp_command_bare),
        *_rows("http:// WebSocket status → wait_until woken", http_status_driver, http_status_bare),
        *_rows("http:// send(Velocity) → PUT at device", http_command_driver, http_command_bare),
        *_age_rows("socket://", ages, None),
        *_age_rows("udp://", udp_ages, ages),
        *_age_rows("http://", http_ages, ages),
    ]
