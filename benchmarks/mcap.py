"""MCAP recording: what McapRecorder costs with N robots at 30 Hz (default 1000).

The robots are served by benchmarks.fleet_server in another process over loopback TCP and
connected as one Fleet (no task per robot: the application only holds them). In every
round, on the same connections, a phase **without** the recorder (the baseline) and a
phase **with** one McapRecorder on the whole fleet (raw bytes, statuses and events of
every robot into one file in a temporary folder). Per phase, over a window:

* CPU per frame: the process's CPU seconds (time.process_time: the loop and the file's
  worker thread) over the frames the links received;
* loop lag: a probe task sleeping 10 ms again and again, how late each wake-up was
  (p99 and the worst);
* in the recorded phase, bytes on disk per status recorded (the file's size over the
  statuses written, the raw and events channels included) and the messages dropped.
"""

from __future__ import annotations

import asyncio
import os
import statistics
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import galileo_async
from galileo_async.fleet import Fleet
from galileo_async.recording import McapRecorder

from .common import Row, percentile, raise_fd_limit
from .fleet import FRAME_SIZE, WARMUP, _Server

__all__ = ["run"]

#: The probe's sleep: a wake-up later than this is loop lag.
PROBE = 0.01


@dataclass
class _Phase:
    cpu: float = 0.0
    frames: int = 0
    lags: list[float] = field(default_factory=list)
    bytes_on_disk: int = 0
    statuses: int = 0
    dropped: int = 0


async def _probe(lags: list[float], stop: asyncio.Event) -> None:
    loop = asyncio.get_running_loop()
    while not stop.is_set():
        began = loop.time()
        await asyncio.sleep(PROBE)
        lags.append(loop.time() - began - PROBE)


def _frames(fleet: Fleet) -> int:
    return sum(fleet[name].link.frames for name in fleet.names)


async def _window(fleet: Fleet, seconds: float) -> _Phase:
    phase = _Phase()
    stop = asyncio.Event()
    probe = asyncio.create_task(_probe(phase.lags, stop))
    frames, cpu = _frames(fleet), time.process_time()
    await asyncio.sleep(seconds)
    phase.cpu, phase.frames = time.process_time() - cpu, _frames(fleet) - frames
    stop.set()
    await probe
    return phase


async def _recorded(fleet: Fleet, seconds: float, folder: Path, index: int) -> _Phase:
    path = folder / f"round{index}.mcap"
    async with McapRecorder(path, fleet) as recorder:
        await asyncio.sleep(WARMUP / 2)
        phase = await _window(fleet, seconds)
    phase.bytes_on_disk = path.stat().st_size
    phase.statuses = recorder.written.get("status", 0)
    phase.dropped = recorder.dropped
    path.unlink()
    return phase


async def _measure(count: int, seconds: float, rounds: int) -> list[tuple[_Phase, _Phase]]:
    loop = asyncio.get_running_loop()
    server = _Server(count)
    results: list[tuple[_Phase, _Phase]] = []
    try:
        ports = {f"r{i}": f"socket://127.0.0.1:{port}" for i, port in enumerate(server.ports)}
        async with galileo_async.connect_fleet(ports, connect_concurrency=100) as fleet:
            await asyncio.sleep(WARMUP)
            with tempfile.TemporaryDirectory() as folder:
                for index in range(rounds):
                    bare = await _window(fleet, seconds)
                    recorded = await _recorded(fleet, seconds, Path(folder), index)
                    results.append((bare, recorded))
    finally:
        await loop.run_in_executor(None, server.close)
    return results


def run(
    *, quick: bool = False, robots: int | None = None, seconds: float | None = None
) -> list[Row]:
    """The recorder's cost with ``robots`` robots (default 1000; --quick: 100)."""
    raise_fd_limit()
    count = robots or (100 if quick else 1000)
    window = seconds or (2.0 if quick else 5.0)
    rounds = 1 if quick else 3
    print(f"  mcap N={count}, {rounds} round(s) of {window:g} s …", flush=True)
    results = asyncio.run(_measure(count, window, rounds))
    bares = [bare for bare, _ in results]
    recs = [recorded for _, recorded in results]
    name = f"mcap N={count}"

    def per_frame(phases: list[_Phase]) -> float:
        return statistics.median(1e6 * p.cpu / max(1, p.frames) for p in phases)

    def lag(phases: list[_Phase], q: float) -> float:
        return statistics.median(1e3 * percentile(p.lags, q) for p in phases)

    statuses = sum(p.statuses for p in recs)
    return [
        Row(name, "CPU per frame, recorder on (the whole process)", per_frame(recs), "µs",
            per_frame(bares), "recorder off", "", None,
            {"frames": [p.frames for p in recs], "cores": os.cpu_count()}),
        Row(name, "loop lag p99 of a 10 ms sleep, recorder on", lag(recs, 99), "ms",
            lag(bares, 99), "recorder off", "", None,
            {"max_ms": [round(1e3 * max(p.lags, default=0), 2) for p in recs],
             "bare_max_ms": [round(1e3 * max(p.lags, default=0), 2) for p in bares]}),
        Row(name, "bytes on disk per status recorded (raw, status, events)",
            sum(p.bytes_on_disk for p in recs) / max(1, statuses), "B",
            float(FRAME_SIZE), "bytes of the frame on the wire", "", None,
            {"statuses": statuses}),
        Row(name, "messages dropped (disk behind)", float(sum(p.dropped for p in recs)), "",
            0.0, "none", "", None),
    ]  # fmt: skip
