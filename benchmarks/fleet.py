"""Fleet: N robots at 30 Hz from another process over loopback TCP, one driver event loop.

Per N, phases on the same server and the same kind of streams, in every round:

* **bare**: N ``asyncio.Protocol`` connections that only count bytes (the baseline);
* **driver**: N ``Robot`` objects (``galileo_async.connect("socket://…")``), each with a
  task iterating ``robot.statuses()``;
* **driver, sampled**: the same robots without those tasks; one task reads every robot's
  ``status`` ten times a second (a dashboard), so only the driver itself runs per frame;
* **bare BufferedProtocol**: the byte count again, reading into a buffer of its own as
  the driver's link does (a reference figure, not a baseline of any target);
* **bare + a task per connection**: the byte count, and a task per connection woken
  through a future on every read: what asyncio alone charges for a task per robot (a
  reference figure).

glibc is pinned to serve asyncio's 256 KiB read buffers from the heap (common.pin_malloc;
``--malloc default`` leaves it be): left alone, the bare baseline's own cost flipped
between about 9 and 15 µs per frame. An untimed bare phase runs first on a fresh server.
Each phase warms up, then measures over a window: process CPU seconds
(time.process_time), frames kept (link counters: frames / (frames + time_stamp gaps)),
and status age.

Status age: the server starts every robot in one loop iteration and reports that
instant (``origin``) on CLOCK_MONOTONIC, which all processes on the host share; frame
``t`` of every robot is due at ``origin + t/30``. A consumer that receives a status
computes ``time.monotonic() - (origin + time_stamp/30)``: the time from the frame's
scheduled send to the application holding it. That includes any lateness of the server
process (it shares the two cores), so it is an upper bound of what the driver adds. In
the statuses() variant AGE_ROBOTS robots (evenly spread) time every status they get; the
others only receive theirs.

Memory per robot: RSS growth from before the robots connected to after the warm-up,
divided by N; and, in a separate pass with tracemalloc on, the Python heap it traced.
"""

from __future__ import annotations

import asyncio
import contextlib
import gc
import json
import statistics
import subprocess
import sys
import time
import tracemalloc
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import galileo_async
from galileo_async import GalileoStatus, Robot

from .common import Row, percentile, pin_malloc, raise_fd_limit, rss_bytes

__all__ = ["run"]

CONNECT_BATCH = 100
WARMUP = 1.5
FRAME_SIZE = 89
#: The fleet size the issue's targets are set at.
TARGET_N = 1000
#: Rounds at TARGET_N (3 at smaller sizes), unless asked for another number.
TARGET_ROUNDS = 5
#: How many robots of a fleet time every status they receive (statuses() variant).
AGE_ROBOTS = 100
#: How often the task-less variant samples every robot's latest status.
SAMPLE_RATE = 10
#: Seconds of an untimed bare phase before the first timed one.
SERVER_WARMUP = 3.0


class _Server:
    """The fleet server process and its control pipe."""

    def __init__(
        self, count: int, env: dict[str, str] | None = None, traffic: str = "burst",
        *, idle: bool = False,
    ) -> None:  # fmt: skip
        idling = ["--idle"] if idle else []
        self.process = subprocess.Popen(
            [sys.executable, "-m", "benchmarks.fleet_server", str(count), "--traffic", traffic,
             *idling],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, env=env,
        )  # fmt: skip
        assert self.process.stdout is not None
        self.info: dict[str, Any] = json.loads(self.process.stdout.readline())
        self.ports: list[int] = self.info["ports"]
        self.origin: float = self.info["origin"]
        self.period: float = self.info["period"]
        #: Robot i's frame t is due at origins[i] + t * period (traffic "spread" staggers them).
        self.origins: list[float] = [self.origin + o for o in self.info["offsets"]]

    def cpu(self) -> dict[str, Any]:
        """The server's CPU seconds and counters (blocks briefly: call between windows)."""
        assert self.process.stdin is not None
        assert self.process.stdout is not None
        self.process.stdin.write("cpu\n")
        self.process.stdin.flush()
        reply: dict[str, Any] = json.loads(self.process.stdout.readline())
        return reply

    def close(self) -> None:
        """End the server process."""
        with contextlib.suppress(OSError):
            assert self.process.stdin is not None
            self.process.stdin.close()
        try:
            self.process.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()


class _Counter(asyncio.Protocol):
    """The baseline: counts bytes, nothing else."""

    def __init__(self) -> None:
        self.bytes = 0
        self.lost: asyncio.Future[None] = asyncio.get_running_loop().create_future()

    def data_received(self, data: bytes) -> None:
        self.bytes += len(data)

    def connection_lost(self, exc: Exception | None) -> None:
        if not self.lost.done():
            self.lost.set_result(None)


class _BufferedCounter(asyncio.BufferedProtocol):
    """The same count, reading into one buffer of its own (as the driver's link does)."""

    def __init__(self) -> None:
        self.bytes = 0
        self.lost: asyncio.Future[None] = asyncio.get_running_loop().create_future()
        self._view = memoryview(bytearray(4096))

    def get_buffer(self, sizehint: int) -> memoryview:
        return self._view

    def buffer_updated(self, nbytes: int) -> None:
        self.bytes += nbytes

    def connection_lost(self, exc: Exception | None) -> None:
        if not self.lost.done():
            self.lost.set_result(None)


class _WakingCounter(_Counter):
    """Counts bytes and wakes a task of its own on every read (the asyncio floor)."""

    def __init__(self) -> None:
        super().__init__()
        self.waiter: asyncio.Future[None] | None = None

    def data_received(self, data: bytes) -> None:
        self.bytes += len(data)
        waiter = self.waiter
        if waiter is not None and not waiter.done():
            waiter.set_result(None)

    async def wait_forever(self) -> None:
        """The task: wait for the next read, again and again."""
        loop = asyncio.get_running_loop()
        while True:
            self.waiter = loop.create_future()
            await self.waiter


@dataclass
class _Phase:
    cpu: float = 0.0
    wall: float = 0.0
    server_cpu: float = 0.0
    frames: int = 0
    lost: int = 0
    ages: list[float] = field(default_factory=list)
    seen: int = 0
    rss_per_robot: float = 0.0
    traced_per_robot: float = 0.0


async def _window(seconds: float, server: _Server) -> tuple[float, float, float]:
    """Sleep through the measurement window; (driver CPU s, wall s, server CPU s)."""
    loop = asyncio.get_running_loop()
    server_before = await loop.run_in_executor(None, server.cpu)
    cpu0, wall0 = time.process_time(), time.perf_counter()
    await asyncio.sleep(seconds)
    cpu, wall = time.process_time() - cpu0, time.perf_counter() - wall0
    server_after = await loop.run_in_executor(None, server.cpu)
    return cpu, wall, server_after["cpu"] - server_before["cpu"]


async def _bare(
    server: _Server, seconds: float, *, kind: str = "protocol", warmup: float = WARMUP
) -> _Phase:
    """Bare counters: ``kind`` "protocol", "buffered" or "tasks" (a woken task each)."""
    loop = asyncio.get_running_loop()
    factories: dict[str, Callable[[], _Counter | _BufferedCounter]] = {
        "protocol": _Counter, "buffered": _BufferedCounter, "tasks": _WakingCounter
    }  # fmt: skip
    factory = factories[kind]
    counters: list[_Counter | _BufferedCounter] = []
    transports: list[asyncio.BaseTransport] = []
    for start in range(0, len(server.ports), CONNECT_BATCH):
        batch = server.ports[start : start + CONNECT_BATCH]
        made = await asyncio.gather(
            *(loop.create_connection(factory, "127.0.0.1", port) for port in batch)
        )
        for made_transport, protocol in made:
            transports.append(made_transport)
            counters.append(protocol)
    tasks = [
        asyncio.create_task(counter.wait_forever())
        for counter in counters
        if isinstance(counter, _WakingCounter)
    ]
    try:
        await asyncio.sleep(warmup)
        before = sum(c.bytes for c in counters)
        phase = _Phase()
        phase.cpu, phase.wall, phase.server_cpu = await _window(seconds, server)
        phase.frames = (sum(c.bytes for c in counters) - before) // FRAME_SIZE
    finally:
        for task in tasks:
            task.cancel()
        await asyncio.gather(*tasks, return_exceptions=True)
        for each in transports:
            each.close()
        await asyncio.wait_for(asyncio.gather(*(c.lost for c in counters)), 10)
    return phase


async def _connect(server: _Server) -> list[Robot]:
    robots: list[Robot] = []
    try:
        for start in range(0, len(server.ports), CONNECT_BATCH):
            batch = server.ports[start : start + CONNECT_BATCH]
            robots += await asyncio.gather(
                *(galileo_async.connect(f"socket://127.0.0.1:{port}") for port in batch)
            )
    except BaseException:
        await asyncio.gather(*(robot.close() for robot in robots), return_exceptions=True)
        raise
    return robots


async def _driver(server: _Server, seconds: float, *, consumers: bool) -> _Phase:
    """Robots with a statuses() task each, or (consumers=False) sampled at SAMPLE_RATE."""
    phase = _Phase()
    origins, period = server.origins, server.period
    recording = False
    ages = phase.ages
    monotonic = time.monotonic

    async def consume(robot: Robot) -> None:
        async for _status in robot.statuses():
            pass

    async def consume_timed(robot: Robot, origin: float) -> None:
        status: GalileoStatus
        async for status in robot.statuses():
            if recording:
                assert status.time_stamp is not None
                ages.append(monotonic() - (origin + status.time_stamp * period))

    async def sample(robots: list[Robot]) -> None:
        # The age a status had when it reached the store: link.last_frame_at is set with it.
        seen: dict[int, int] = {}
        while True:
            await asyncio.sleep(1 / SAMPLE_RATE)
            if not recording:
                continue
            for index, robot in enumerate(robots):
                status, arrived = robot.status, robot.link.last_frame_at
                if status is None or arrived is None or status.time_stamp is None:
                    continue
                if seen.get(index) != status.time_stamp:
                    seen[index] = status.time_stamp
                    ages.append(arrived - (origins[index] + status.time_stamp * period))

    gc.collect()
    rss0 = rss_bytes()
    robots = await _connect(server)
    if consumers:
        # At most AGE_ROBOTS robots time their statuses: the age is a sample, and its
        # bookkeeping (a clock read and a list append per status) is not the driver's cost.
        every = max(1, len(robots) // AGE_ROBOTS)
        tasks = [
            asyncio.create_task(
                consume_timed(robot, origins[index]) if index % every == 0 else consume(robot)
            )
            for index, robot in enumerate(robots)
        ]
    else:
        tasks = [asyncio.create_task(sample(robots))]
    try:
        await asyncio.sleep(WARMUP)
        gc.collect()
        phase.rss_per_robot = (rss_bytes() - rss0) / len(robots)
        frames0 = sum(robot.link.frames for robot in robots)
        lost0 = sum(robot.link.lost_frames for robot in robots)
        reconnects0 = sum(robot.link.reconnects for robot in robots)
        recording = True
        phase.cpu, phase.wall, phase.server_cpu = await _window(seconds, server)
        recording = False
        phase.frames = sum(robot.link.frames for robot in robots) - frames0
        phase.lost = sum(robot.link.lost_frames for robot in robots) - lost0
        reconnects = sum(robot.link.reconnects for robot in robots) - reconnects0
        assert reconnects == 0, f"{reconnects} reconnects during the window"
        phase.seen = len(ages)
    finally:
        for task in tasks:
            task.cancel()
        await asyncio.gather(*tasks, return_exceptions=True)
        await asyncio.gather(*(robot.close() for robot in robots))
    return phase


async def _traced(server: _Server) -> float:
    """Python heap per robot (tracemalloc) for connected robots with one consumer each."""
    gc.collect()
    tracemalloc.start()
    try:
        base = tracemalloc.get_traced_memory()[0]
        robots = await _connect(server)

        async def consume(robot: Robot) -> None:
            async for _status in robot.statuses():
                pass

        tasks = [asyncio.create_task(consume(robot)) for robot in robots]
        await asyncio.sleep(WARMUP)
        gc.collect()
        traced = (tracemalloc.get_traced_memory()[0] - base) / len(robots)
        for task in tasks:
            task.cancel()
        await asyncio.gather(*tasks, return_exceptions=True)
        await asyncio.gather(*(robot.close() for robot in robots))
    finally:
        tracemalloc.stop()
    return traced


async def _measure(
    count: int, seconds: float, repeats: int, traffic: str = "burst"
) -> list[tuple[_Phase, ...]]:
    """``repeats`` rounds of (bare, driver with tasks, driver sampled) on one server."""
    server = _Server(count, traffic=traffic)
    rounds: list[tuple[_Phase, ...]] = []
    try:
        # Untimed: the first phase after the server starts warms both processes up.
        await _bare(server, SERVER_WARMUP)
        for _ in range(repeats):
            bare = await _bare(server, seconds)
            driver = await _driver(server, seconds, consumers=True)
            sampled = await _driver(server, seconds, consumers=False)
            buffered = await _bare(server, seconds, kind="buffered")
            waking = await _bare(server, seconds, kind="tasks")
            rounds.append((bare, driver, sampled, buffered, waking))
        rounds[0][1].traced_per_robot = await _traced(server)
    finally:
        await asyncio.get_running_loop().run_in_executor(None, server.close)
    return rounds


def run(
    *,
    quick: bool = False,
    sizes: list[int] | None = None,
    seconds: float = 10.0,
    repeats: int | None = None,
    malloc: str = "heap",
    traffic: str = "burst",
) -> list[Row]:
    """Measure the fleet for each N in ``sizes`` (``malloc``: see common.pin_malloc).

    ``traffic``: "burst" (every robot's frame of a tick written together) or "spread".
    """
    raise_fd_limit()
    pinned = malloc == "heap" and pin_malloc()
    print(f"  glibc read buffers: {'pinned to the heap' if pinned else 'not pinned'}", flush=True)
    rows: list[Row] = []
    for count in sizes or [10, 100, 1000]:
        # The verdict is the median of per-round ratios, and the bare baseline alone moves
        # by up to a third between rounds (BENCHMARKS.md §2): three rounds at least, five
        # at the size the targets are set at, whose ratio lies near its line.
        rounds_wanted = repeats or (1 if quick else TARGET_ROUNDS if count >= TARGET_N else 3)
        print(f"  fleet N={count}, {traffic}, {rounds_wanted} round(s) …", flush=True)
        rounds = asyncio.run(_measure(count, seconds, rounds_wanted, traffic))
        bares = [r[0] for r in rounds]
        name = f"fleet N={count}" + ("" if traffic == "burst" else f" {traffic}")
        rows += _rows(name, count, bares, [r[1] for r in rounds], "statuses() task per robot")
        rows += _rows(name, count, bares, [r[2] for r in rounds], "no task, app samples status",
                      memory=False)  # fmt: skip
        rows.append(_reference_row(name, bares, [r[3] for r in rounds],
                                   "bare BufferedProtocol CPU (for reference)"))  # fmt: skip
        rows.append(_reference_row(name, bares, [r[4] for r in rounds],
                                   "bare + a task per connection CPU (for reference)"))  # fmt: skip
    return rows


def _reference_row(name: str, bares: list[_Phase], phases: list[_Phase], metric: str) -> Row:
    """A bare variant's CPU next to the bare Protocol's (no target: a reference)."""
    return Row(
        name, metric,
        100 * statistics.median(p.cpu / p.wall for p in phases), "% of a core",
        100 * statistics.median(b.cpu / b.wall for b in bares), "bare Protocol", "", None,
        {"us_per_frame_rounds": [round(1e6 * p.cpu / max(1, p.frames), 2) for p in phases],
         "bare_us_per_frame_rounds": [round(1e6 * b.cpu / max(1, b.frames), 2)
                                      for b in bares],
         "ratios": [round((p.cpu / p.wall) / (b.cpu / b.wall), 2)
                    for b, p in zip(bares, phases, strict=True)]},
    )  # fmt: skip


def _rows(
    name: str,
    count: int,
    bares: list[_Phase],
    drivers: list[_Phase],
    how: str,
    *,
    memory: bool = True,
) -> list[Row]:
    wall = sum(d.wall for d in drivers)
    frames, lost = sum(d.frames for d in drivers), sum(d.lost for d in drivers)
    kept = frames / max(1, frames + lost)
    ages = [age for d in drivers for age in d.ages]
    p50, p99 = percentile(ages, 50), percentile(ages, 99)
    # Ratio per round (bare and driver measured minutes apart at most), then the median.
    ratios = [(d.cpu / d.wall) / (b.cpu / b.wall) for b, d in zip(bares, drivers, strict=True)]
    ratio = statistics.median(ratios)
    driver_cpu = statistics.median(d.cpu / d.wall for d in drivers)
    bare_cpu = statistics.median(b.cpu / b.wall for b in bares)
    bare_frames = sum(b.frames for b in bares) / (count * 30 * sum(b.wall for b in bares))
    # The targets are set at N = TARGET_N; smaller fleets show how the figures grow.
    held = count >= TARGET_N

    def target(text: str, met: bool) -> tuple[str, bool | None]:
        return (text, met) if held else (f"{text} at N={TARGET_N}", None)

    common = {"how": how, "rounds": len(drivers), "window_s": round(wall / len(drivers), 2),
              "server_cpu_s": [round(d.server_cpu, 2) for d in drivers]}  # fmt: skip
    rows = [
        Row(name, f"frames kept ({how})", 100 * kept, "%", 100 * bare_frames,
            "bare: bytes/89 vs 30 Hz", *target("≥ 99.9 %", kept >= 0.999),
            {"frames": frames, "lost": lost, "received_vs_30Hz": frames / (count * 30 * wall),
             **common}),
        Row(name, f"driver CPU ({how})", 100 * driver_cpu, "% of a core", 100 * bare_cpu,
            "bare Protocol", *target("≤ 1.5× bare", ratio <= 1.5),
            {"ratio_median": ratio, "ratios": [round(r, 2) for r in ratios],
             "us_per_frame_rounds": [round(1e6 * d.cpu / max(1, d.frames), 2) for d in drivers],
             "bare_us_per_frame_rounds": [round(1e6 * b.cpu / max(1, b.frames), 2)
                                          for b in bares],
             "us_per_frame": 1e6 * sum(d.cpu for d in drivers) / max(1, frames),
             "bare_us_per_frame": 1e6 * sum(b.cpu for b in bares)
             / max(1, sum(b.frames for b in bares)), **common}),
        Row(name, f"status age p99 ({how})", 1000 * p99, "ms", 1000 * p50, "p50",
            *target("≤ 100 ms", p99 <= 0.100), {"max_ms": 1000 * max(ages, default=float("nan")),
                           "samples": len(ages), **common}),
    ]  # fmt: skip
    if memory:
        first = drivers[0]
        worst = max(first.rss_per_robot, first.traced_per_robot)
        rows.append(
            Row(name, "memory per robot: RSS growth", first.rss_per_robot / 1024, "KiB",
                first.traced_per_robot / 1024, "tracemalloc",
                *target("≤ 64 KiB (both)", worst <= 64 * 1024))
        )  # fmt: skip
    return rows
