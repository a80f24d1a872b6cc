"""Ingest: µs per status frame, framing + unpack and the full path, next to a raw baseline.

The frames come from the simulator's robot model driving goals (values change frame to
frame, as on a real robot) and are fed one frame per chunk, as a 30 Hz link delivers them.
The baseline is the least any decoder must do: ``bytes.find(header)`` + ``unpack_from``.
Each variant runs ``repeats`` times, interleaved; the best run counts (the usual rule for
micro-benchmarks on a shared machine: noise only ever adds time).
"""

from __future__ import annotations

import asyncio
import gc
import time
from collections.abc import Callable
from typing import Any

from galileo_async.models import GalileoStatus, StatusLayout, TargetStatus
from galileo_async.protocol import HEADER, LAYOUTS, StatusDecoder, encode_status
from galileo_async.protocol import commands as cmd
from galileo_async.sim import RobotModel, SimConfig
from galileo_async.state import StatusStore
from galileo_async.transports import Connector, Link, StreamChannel

from .common import Row

__all__ = ["make_frames", "null_connector", "run"]

#: Statuses() consumers, watches and wait_until waiters on the store in the full path.
STREAMS, WATCHES, WAITERS = 3, 1, 1


def make_frames(count: int) -> list[bytes]:
    """``count`` v2 frames of a robot that starts navigation and drives goals in a loop."""
    model = RobotModel(SimConfig(seed=1))
    model.submit(cmd.StartNavigation())
    frames: list[bytes] = []
    goal = 0
    while len(frames) < count:
        model.tick()
        if model.visual_initialised and model.target_status != 1 and not model.busy:
            goal = (goal + 1) % len(model.targets)
            model.submit(cmd.Goto(goal))
        frames.append(encode_status(model.status(), StatusLayout.V2))
    return frames


def _best(function: Callable[[], float], repeats: int) -> float:
    return min(function() for _ in range(repeats))


def _time_raw(frames: list[bytes]) -> float:
    unpack_from = LAYOUTS[StatusLayout.V2].struct.unpack_from
    header = HEADER
    start = time.perf_counter()
    for chunk in frames:
        pos = chunk.find(header)
        if pos >= 0:
            unpack_from(chunk, pos + 4)
    return (time.perf_counter() - start) / len(frames)


def _time_raw_buffer(buffer: bytes, count: int) -> float:
    unpack_from = LAYOUTS[StatusLayout.V2].struct.unpack_from
    header, find = HEADER, buffer.find
    start = time.perf_counter()
    pos = find(header)
    while pos >= 0:
        unpack_from(buffer, pos + 4)
        pos = find(header, pos + 89)
    return (time.perf_counter() - start) / count


def _time_decoder(frames: list[bytes], method: str) -> float:
    decoder = StatusDecoder()
    feed = getattr(decoder, method)
    start = time.perf_counter()
    for chunk in frames:
        feed(chunk)
    elapsed = time.perf_counter() - start
    assert decoder.stats.frames == len(frames), decoder.stats
    return elapsed / len(frames)


def _time_decoder_buffer(buffer: bytes, count: int) -> float:
    decoder = StatusDecoder()
    start = time.perf_counter()
    decoder.feed_raw(buffer)
    elapsed = time.perf_counter() - start
    assert decoder.stats.frames == count
    return elapsed / count


class _NullTransport(asyncio.WriteTransport):
    """Accepts writes and drops them; the full path only reads."""

    def __init__(self, protocol: asyncio.Protocol) -> None:
        super().__init__()
        self._protocol = protocol
        self._closing = False

    def write(self, data: Any) -> None:
        pass

    def is_closing(self) -> bool:
        return self._closing

    def close(self) -> None:
        if not self._closing:
            self._closing = True
            asyncio.get_running_loop().call_soon(self._protocol.connection_lost, None)

    def abort(self) -> None:
        self.close()


def null_connector(protocols: list[Any]) -> Connector:
    """A connector of links over a _NullTransport; each protocol it makes joins ``protocols``."""

    async def connector(
        loop: asyncio.AbstractEventLoop, factory: Callable[[], asyncio.Protocol]
    ) -> tuple[asyncio.BaseTransport, asyncio.Protocol]:
        protocol = factory()
        transport = _NullTransport(protocol)
        protocol.connection_made(transport)
        protocols.append(protocol)
        return transport, protocol

    return connector


async def _full_path(
    frames: list[bytes],
    repeats: int,
    *,
    streams: int = STREAMS,
    watches: int = WATCHES,
    waiters: int = WAITERS,
) -> tuple[float, float]:
    """(s in data_received per frame, s per frame including the consumers' wake-ups)."""
    protocols: list[asyncio.Protocol] = []
    store = StatusStore()
    link = Link(
        StreamChannel(null_connector(protocols)), store, stale_timeout=None, reconnect=False
    )
    await link.open()
    received = [0] * (streams + watches)

    async def consume_stream(index: int) -> None:
        async for _status in store.statuses():
            received[index] += 1

    async def consume_watch(index: int) -> None:
        with store.watch() as watch:
            async for _status in watch:
                received[index] += 1

    def never(status: GalileoStatus) -> bool:
        return status.target_status == TargetStatus.ERROR

    tasks: list[asyncio.Task[Any]] = []
    tasks += [asyncio.create_task(consume_stream(i)) for i in range(streams)]
    tasks += [asyncio.create_task(consume_watch(streams + i)) for i in range(watches)]
    tasks += [asyncio.create_task(store.wait_until(never)) for _ in range(waiters)]
    if not received:
        received = [1]
    await asyncio.sleep(0)
    protocol = protocols[0]
    data_received = protocol.data_received
    best_sync = best_total = float("inf")
    perf = time.perf_counter
    try:
        for _ in range(repeats):
            in_path = 0.0
            start = perf()
            for chunk in frames:
                t0 = perf()
                data_received(chunk)
                in_path += perf() - t0
                await asyncio.sleep(0)  # the consumers take their status
            total = perf() - start
            best_sync = min(best_sync, in_path / len(frames))
            best_total = min(best_total, total / len(frames))
        assert link.stats.frames == repeats * len(frames), link.stats
        assert min(received) > 0, received
    finally:
        for task in tasks:
            task.cancel()
        await asyncio.gather(*tasks, return_exceptions=True)
        await link.close()
    return best_sync, best_total


async def _wake_floor(count: int, frames: int, repeats: int) -> float:
    """s per frame asyncio itself takes to wake ``count`` waiting tasks (set_result each)."""
    loop = asyncio.get_running_loop()
    boxes: list[list[asyncio.Future[None]]] = [[loop.create_future()] for _ in range(count)]

    async def waiter(box: list[asyncio.Future[None]]) -> None:
        while True:
            await box[0]
            box[0] = loop.create_future()

    tasks = [asyncio.create_task(waiter(box)) for box in boxes]
    await asyncio.sleep(0)
    perf = time.perf_counter
    best = float("inf")
    try:
        for _ in range(repeats):
            spent = 0.0
            for _ in range(frames):
                t0 = perf()
                for box in boxes:
                    box[0].set_result(None)
                spent += perf() - t0
                await asyncio.sleep(0)  # the waiters run and wait again, as consumers do
            best = min(best, spent / frames)
    finally:
        for task in tasks:
            task.cancel()
        await asyncio.gather(*tasks, return_exceptions=True)
    return best


def run(*, quick: bool = False) -> list[Row]:
    """Measure ingest and return its rows."""
    count = 2_000 if quick else 10_000
    repeats = 3 if quick else 7
    frames = make_frames(count)
    buffer = b"".join(frames)
    gc.collect()
    raw = _best(lambda: _time_raw(frames), repeats)
    framing = _best(lambda: _time_decoder(frames, "feed_raw"), repeats)
    decode = _best(lambda: _time_decoder(frames, "feed"), repeats)
    raw_buffer = _best(lambda: _time_raw_buffer(buffer, count), repeats)
    framing_buffer = _best(lambda: _time_decoder_buffer(buffer, count), repeats)
    full_sync, full_total = asyncio.run(_full_path(frames, max(2, repeats // 2)))
    rounds = max(2, repeats // 2)
    bare_sync, _ = asyncio.run(_full_path(frames, rounds, streams=0, watches=0, waiters=0))
    one_sync, _ = asyncio.run(_full_path(frames, rounds, streams=1, watches=0, waiters=1))
    woken = STREAMS + WATCHES
    floor = asyncio.run(_wake_floor(woken, len(frames), rounds))
    us = 1e6
    ratio = raw_buffer / framing_buffer
    rows = [
        Row("ingest", f"framing+unpack, one {len(buffer) // 1000} kB buffer",
            framing_buffer * us, "µs/frame", raw_buffer * us, "find+unpack_from",
            "rate ≥ 0.5× baseline", ratio >= 0.5, {"rate_vs_baseline": ratio}),
        Row("ingest", "framing+unpack, one frame per read", framing * us, "µs/frame",
            raw * us, "find+unpack_from", "", None, {"rate_vs_baseline": raw / framing}),
        Row("ingest", "decode → GalileoStatus", decode * us, "µs/frame",
            raw * us, "find+unpack_from"),
        Row("ingest", "full path, 3 statuses() + 1 watch + 1 wait_until", full_sync * us,
            "µs/frame", raw * us, "find+unpack_from", "≤ 5 µs/frame", full_sync * us <= 5.0,
            {"streams": STREAMS, "watches": WATCHES, "waiters": WAITERS}),
        Row("ingest", "full path, nobody subscribed", bare_sync * us, "µs/frame",
            raw * us, "find+unpack_from"),
        Row("ingest", "full path, 1 statuses() + 1 wait_until", one_sync * us, "µs/frame",
            raw * us, "find+unpack_from"),
        Row("ingest", "full path + consumers run (loop turn)", full_total * us, "µs/frame",
            raw * us, "find+unpack_from"),
        Row("ingest", f"asyncio alone: wake {woken} waiting tasks (set_result each)",
            floor * us, "µs/frame", None, "", "", None,
            {"note": "part of the 5-subscriber full path no driver code can remove"}),
    ]  # fmt: skip
    return rows
