"""Fleet, merged: N robots at 30 Hz over loopback TCP and ONE ``fleet.statuses()`` consumer.

The same server and phases as ``fleet`` (benchmarks/fleet.py), per round:

* **bare**: N ``asyncio.Protocol`` connections that only count bytes;
* **bare BufferedProtocol**: the byte count read into a buffer of its own, as the driver's
  link reads (the floor the issue names);
* **fleet.statuses()**: ``connect_fleet`` with the N ``socket://`` robots and one task
  iterating ``fleet.statuses()``: every robot's newest status, coalesced, no task per
  robot. AGE_ROBOTS robots (evenly spread) time every status the consumer gets;
* **a statuses() task per robot**: ``fleet``'s driver phase, N ``connect()`` robots each
  with a task iterating ``robot.statuses()``, what the merged stream replaces;
* **driver alone**: ``fleet``'s sampled phase, N ``connect()`` robots and no task per robot
  (one task reads every robot's ``status`` ten times a second).

``traffic`` "burst" (default): the server writes every robot's frame of a tick back to back,
so the driver finds them ready together (reads batched); "spread": the robots' frames are
staggered over the period (benchmarks/fleet_server.py).

Status age and memory per robot are measured as in ``fleet``; the CPU ratio is taken per
round against the BufferedProtocol floor of that round, then the median. After each
window, the ``galileo fleet monitor`` screen (table sorted by distance, summary, map of
every robot) is drawn RENDERS times into a 160 x 60 terminal, fed by a merged stream of
its own: how long one drawing takes.
"""

from __future__ import annotations

import asyncio
import gc
import io
import statistics
import time

from rich.console import Console

from galileo_async import Fleet, connect_fleet
from galileo_async.cli.fleet_cmd import FLEET_REFRESH
from galileo_async.cli.fleet_view import FleetView
from galileo_async.cli.map_model import MapModel

from .common import Row, percentile, pin_malloc, raise_fd_limit, rss_bytes
from .fleet import (
    AGE_ROBOTS,
    SERVER_WARMUP,
    TARGET_N,
    WARMUP,
    _bare,
    _driver,
    _Phase,
    _Server,
    _window,
)

__all__ = ["merged_phase", "run"]

#: Screens of the fleet monitor drawn per round, at its refresh rate, after the window.
RENDERS = 8


async def merged_phase(server: _Server, seconds: float, renders: list[float]) -> _Phase:
    """Robots in one Fleet, one task reading fleet.statuses(); CPU, frames, ages, memory.

    After the window, the fleet monitor's screen is drawn RENDERS times; ``renders`` gets
    the seconds each drawing took.
    """
    phase = _Phase()
    period = server.period
    ports = {f"r{index}": f"socket://127.0.0.1:{port}" for index, port in enumerate(server.ports)}
    every = max(1, len(ports) // AGE_ROBOTS)
    timed = {name: server.origins[index] for index, name in enumerate(ports) if index % every == 0}
    recording = False
    ages = phase.ages
    monotonic = time.monotonic
    received = [0]

    async def consume(fleet: Fleet) -> None:
        count = 0
        async for name, status in fleet.statuses():
            count += 1
            if recording and name in timed:
                assert status.time_stamp is not None
                ages.append(monotonic() - (timed[name] + status.time_stamp * period))
            received[0] = count

    gc.collect()
    rss0 = rss_bytes()
    async with connect_fleet(ports, retry_initial=5.0) as fleet:
        down = [name for name in fleet if fleet.get(name) is None]
        assert not down, f"{len(down)} robots did not connect"
        robots = [fleet[name] for name in fleet]
        task = asyncio.create_task(consume(fleet))
        try:
            await asyncio.sleep(WARMUP)
            gc.collect()
            phase.rss_per_robot = (rss_bytes() - rss0) / len(robots)
            frames0 = sum(robot.link.frames for robot in robots)
            lost0 = sum(robot.link.lost_frames for robot in robots)
            received0 = received[0]
            recording = True
            phase.cpu, phase.wall, phase.server_cpu = await _window(seconds, server)
            recording = False
            phase.frames = sum(robot.link.frames for robot in robots) - frames0
            phase.lost = sum(robot.link.lost_frames for robot in robots) - lost0
            phase.seen = received[0] - received0
            renders.extend(await _render_times(fleet))
        finally:
            task.cancel()
            await asyncio.gather(task, return_exceptions=True)
    return phase


async def _render_times(fleet: Fleet) -> list[float]:
    """Seconds per drawing of `galileo fleet monitor`'s screen, fed by its own merged stream."""
    view = FleetView(fleet, MapModel(), sort="distance")
    console = Console(file=io.StringIO(), width=160, height=60, force_terminal=True)

    async def feed() -> None:
        async for name, status in fleet.statuses():
            view.latest[name] = view.changed[name] = status

    task = asyncio.create_task(feed())
    times = []
    try:
        for _ in range(RENDERS):
            await asyncio.sleep(1 / FLEET_REFRESH)
            began = time.perf_counter()
            console.print(view.screen())
            times.append(time.perf_counter() - began)
    finally:
        task.cancel()
        await asyncio.gather(task, return_exceptions=True)
    return times


async def _measure(
    count: int, seconds: float, repeats: int, renders: list[float], traffic: str = "burst"
) -> list[tuple[_Phase, ...]]:
    """``repeats`` rounds of (bare Protocol, BufferedProtocol, merged, task per robot, alone)."""
    server = _Server(count, traffic=traffic)
    rounds: list[tuple[_Phase, ...]] = []
    try:
        await _bare(server, SERVER_WARMUP)  # untimed: warms both processes up
        for _ in range(repeats):
            bare = await _bare(server, seconds)
            buffered = await _bare(server, seconds, kind="buffered")
            merged = await merged_phase(server, seconds, renders)
            tasks = await _driver(server, seconds, consumers=True)
            alone = await _driver(server, seconds, consumers=False)
            rounds.append((bare, buffered, merged, tasks, alone))
    finally:
        await asyncio.get_running_loop().run_in_executor(None, server.close)
    return rounds


def run(
    *,
    quick: bool = False,
    sizes: list[int] | None = None,
    seconds: float = 6.0,
    repeats: int | None = None,
    malloc: str = "heap",
    traffic: str = "burst",
) -> list[Row]:
    """Measure one merged consumer for each N in ``sizes`` against the bare floors.

    ``traffic``: "burst" (every robot's frame of a tick written together) or "spread".
    """
    raise_fd_limit()
    if malloc == "heap":
        pin_malloc()
    rows: list[Row] = []
    for count in sizes or [TARGET_N]:
        wanted = repeats or (1 if quick else 3)
        print(f"  fleet.statuses() N={count}, {traffic}, {wanted} round(s) …", flush=True)
        renders: list[float] = []
        rounds = asyncio.run(_measure(count, seconds, wanted, renders, traffic))
        rows += _rows(count, rounds, renders, traffic)
    return rows


#: The three ways application code gets statuses, by their index in a round.
VARIANTS = (
    (2, "one fleet.statuses() consumer"),
    (3, "a statuses() task per robot"),
    (4, "driver alone (no task per robot)"),
)


def _rows(
    count: int, rounds: list[tuple[_Phase, ...]], renders: list[float], traffic: str = "burst"
) -> list[Row]:
    name = f"fleet.statuses() N={count} {traffic}"
    held = count >= TARGET_N

    def target(text: str, met: bool) -> tuple[str, bool | None]:
        return (text, met) if held else (f"{text} at N={TARGET_N}", None)

    def load(phase: _Phase) -> float:
        return phase.cpu / phase.wall

    def per_frame(phases: list[_Phase]) -> list[float]:
        return [round(1e6 * p.cpu / max(1, p.frames), 2) for p in phases]

    buffered = [r[1] for r in rounds]
    rows: list[Row] = []
    for index, how in VARIANTS:
        phases = [r[index] for r in rounds]
        ratios = [load(p) / load(b) for p, b in zip(phases, buffered, strict=True)]
        ratio = statistics.median(ratios)
        ages = [age for phase in phases for age in phase.ages]
        frames, lost = sum(p.frames for p in phases), sum(p.lost for p in phases)
        kept = frames / max(1, frames + lost)
        p99 = percentile(ages, 99)
        extra = {
            "ratio_median": ratio,
            "ratios_vs_buffered": [round(r, 2) for r in ratios],
            "ratios_vs_protocol": [round(load(p) / load(r[0]), 2)
                                   for p, r in zip(phases, rounds, strict=True)],
            "us_per_frame_rounds": per_frame(phases),
            "buffered_us_per_frame_rounds": per_frame(buffered),
            "rounds": len(rounds),
            "traffic": traffic,
        }  # fmt: skip
        if index == 2:
            extra["statuses_received_per_frame"] = round(
                sum(p.seen for p in phases) / max(1, frames), 3
            )
        rss = phases[0].rss_per_robot
        rows += [
            Row(name, f"frames kept, {how}", 100 * kept, "%", None, "",
                *target("= 100 %", lost == 0), {"frames": frames, "lost": lost}),
            Row(name, f"driver CPU, {how}", 100 * statistics.median(load(p) for p in phases),
                "% of a core", 100 * statistics.median(load(b) for b in buffered),
                "bare BufferedProtocol", *target("≤ 1.5× bare BufferedProtocol", ratio <= 1.5),
                extra),
            Row(name, f"status age p99, {how}", 1000 * p99, "ms", 1000 * percentile(ages, 50),
                "p50", *target("≤ 100 ms", p99 <= 0.1), {"samples": len(ages)}),
            Row(name, f"memory per robot: RSS growth, {how}", rss / 1024, "KiB", None, "",
                *target("≤ 32 KiB", rss <= 32 * 1024)),
        ]  # fmt: skip
    rows.append(
        Row(name, "fleet monitor: one screen drawn (median)", 1000 * statistics.median(renders),
            "ms", 1000 * max(renders), "max", f"< {1000 / FLEET_REFRESH:.0f} ms (its period)",
            None, {"renders": len(renders)}),
    )  # fmt: skip
    return rows
