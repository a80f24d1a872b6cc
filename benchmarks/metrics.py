"""Prometheus metrics of N robots in one process: the collector's CPU and memory, scrapes.

``python -m benchmarks metrics [--robots N] [--[no-]robots-process]``. The N robots are
simulated robots served by a ``benchmarks.fleet_server`` process (traffic spread over the
frame period), each connected here over ``socket://`` (from ROBOTS_PROCESS_FROM robots on, by
default), else in-process ``sim://`` robots. One Metrics follows all of them.

* **CPU per robot**: this process's CPU time over the window / wall time / N, with the
  collector following every robot (no scrape in the window). Baseline, same run: the same
  robots with no collector; the phases alternate, ROUNDS of each, medians reported.
* **collector's CPU**: the difference times N, in cores.
* **scrape**: GET /metrics of serve_metrics on loopback from this process, SCRAPES times
  one per SCRAPE_PERIOD
  (p50, p99 in ms, end to end: collect, encode, HTTP), Prometheus text and OpenMetrics;
  the size of one answer.
* **CPU of a scrape's read and encoding**: process CPU time of reading every family and
  encoding it, step by step as serve_metrics does (STEP_ROUNDS, median): unlike wall
  times, not inflated by other load on the machine. **Longest step**: the longest the
  loop waits for one family. **CPU per scrape over HTTP**: this process's CPU over the
  scrapes' window, less the followed robots' share of it, / scrapes (client included).
* **loop lag**: how late a 10 ms sleep of this loop wakes (p99) while it is scraped every
  SCRAPE_PERIOD; baseline, same run: the same robots and collector, no scrape. A scrape
  reads the robots on the loop and encodes one metric at a time, the loop running between.
* **RSS per robot followed**: this process's resident memory after Metrics follows every
  robot, less just before, / N.
"""

from __future__ import annotations

import asyncio
import statistics
import time
from collections.abc import AsyncIterator
from contextlib import AsyncExitStack, asynccontextmanager
from typing import Any

import aiohttp
from prometheus_client.exposition import generate_latest as text_latest
from prometheus_client.metrics_core import Metric
from prometheus_client.openmetrics.exposition import generate_latest as om_latest
from prometheus_client.registry import Collector

import galileo_async
from galileo_async import Robot
from galileo_async.metrics import Metrics, serve_metrics

from .common import Row, percentile, raise_fd_limit, rss_bytes
from .fleet import _connect, _Server

__all__ = ["ROBOTS_PROCESS_FROM", "measure", "run"]

#: From this many robots on, the robots run in their own process unless told otherwise.
ROBOTS_PROCESS_FROM = 500
#: Bare and followed windows, alternating.
ROUNDS = 3
#: Scrapes per format.
SCRAPES = 10
#: Scrapes timed step by step, per format.
STEP_ROUNDS = 5
#: Seconds between two scrapes (Prometheus's default is 15 s; 1 s is a busy dashboard).
SCRAPE_PERIOD = 1.0
OPENMETRICS = "application/openmetrics-text; version=1.0.0"


@asynccontextmanager
async def _robots(count: int, server: _Server | None) -> AsyncIterator[list[Robot]]:
    """``count`` in-process sim robots, or the server's robots connected over ``socket://``."""
    async with AsyncExitStack() as stack:
        if server is not None:
            robots = await _connect(server)
            for robot in robots:
                stack.push_async_callback(robot.close)
        else:
            robots = [
                await stack.enter_async_context(galileo_async.connect("sim://"))
                for _ in range(count)
            ]
        yield robots


async def _cores(seconds: float) -> float:
    """This process's CPU over ``seconds`` of wall time, in cores."""
    cpu, wall = time.process_time(), time.perf_counter()
    await asyncio.sleep(seconds)
    return (time.process_time() - cpu) / (time.perf_counter() - wall)


def _steps(metrics: Metrics, openmetrics: bool) -> list[float]:
    """CPU seconds of each step of one scrape as serve_metrics takes them: a family read
    and encoded (process time: the machine's other load does not count)."""
    encode = om_latest if openmetrics else text_latest
    steps = []
    families = metrics.collect()
    while True:
        began = time.process_time()
        family = next(families, None)
        if family is None:
            return steps
        encode(_One(family))
        steps.append(time.process_time() - began)


class _One(Collector):
    def __init__(self, family: Metric) -> None:
        self.family = family

    def collect(self) -> list[Metric]:
        return [self.family]


async def _lags(lags: list[float]) -> None:
    """How late each 10 ms sleep of this loop wakes, into ``lags`` (s), until cancelled."""
    loop = asyncio.get_running_loop()
    while True:
        began = loop.time()
        await asyncio.sleep(0.01)
        lags.append(loop.time() - began - 0.01)


async def _lagging(seconds: float) -> list[float]:
    """The loop's lags over ``seconds`` with nothing else added."""
    lags: list[float] = []
    probe = asyncio.ensure_future(_lags(lags))
    await asyncio.sleep(seconds)
    probe.cancel()
    return lags


async def _scrapes(
    url: str, accept: str | None, count: int, period: float
) -> tuple[list[float], int]:
    """``count`` GETs of ``url``, one per ``period``: their times in s, the last one's size."""
    headers = {} if accept is None else {"Accept": accept}
    times: list[float] = []
    size = 0
    async with aiohttp.ClientSession() as session:
        for _ in range(count):
            began = time.perf_counter()
            async with session.get(url, headers=headers) as answer:
                body = await answer.read()
            times.append(time.perf_counter() - began)
            size = len(body)
            await asyncio.sleep(max(0.0, period - times[-1]))
    return times, size


async def measure(
    count: int, seconds: float, *, server: _Server | None = None, scrapes: int = SCRAPES,
    rounds: int = ROUNDS, period: float = SCRAPE_PERIOD,
) -> dict[str, Any]:  # fmt: skip
    """Bare and followed windows of ``count`` robots, RSS of following them, scrape times."""
    bare: list[float] = []
    followed: list[float] = []
    rss = 0.0
    async with _robots(count, server) as robots:
        await asyncio.sleep(1.0)  # every robot's frames flowing
        for round_ in range(rounds):
            bare.append(await _cores(seconds))
            before = rss_bytes()
            metrics = Metrics()
            for index, robot in enumerate(robots):
                metrics.add_robot(robot, name=f"robot{index}")
            if round_ == 0:
                rss = (rss_bytes() - before) / count
            followed.append(await _cores(seconds))
            if round_ < rounds - 1:
                metrics.close()
        frames = sum(robot.link.frames for robot in robots)
        quiet = await _lagging(seconds)
        scraped: list[float] = []
        probe = asyncio.ensure_future(_lags(scraped))
        cpu, wall = time.process_time(), time.perf_counter()
        async with serve_metrics(metrics, port=0) as endpoint:
            text, text_size = await _scrapes(endpoint.url, None, scrapes, period)
            om, om_size = await _scrapes(endpoint.url, OPENMETRICS, scrapes, period)
        cpu, wall = time.process_time() - cpu, time.perf_counter() - wall
        probe.cancel()
        steps = [_steps(metrics, each) for each in (False, True) for _ in range(STEP_ROUNDS)]
        # What the scrapes cost beyond following: CPU seconds per scrape.
        per_scrape = (cpu - statistics.median(followed) * wall) / (2 * scrapes)
        metrics.close()
    return {
        "bare": statistics.median(bare), "followed": statistics.median(followed),
        "rss_per_robot": rss, "text": text, "text_size": text_size, "openmetrics": om,
        "openmetrics_size": om_size, "frames": frames,
        "lag_quiet": quiet, "lag_scraped": scraped, "cpu_per_scrape": per_scrape, "period": period,
        "text_cpu": statistics.median(sum(s) for s in steps[:STEP_ROUNDS]),
        "openmetrics_cpu": statistics.median(sum(s) for s in steps[STEP_ROUNDS:]),
        "longest_step": statistics.median(max(s) for s in steps),
    }  # fmt: skip


def run(
    quick: bool = False,
    robots: int | None = None,
    seconds: float | None = None,
    robots_process: bool | None = None,
) -> list[Row]:
    """The metrics rows for ``robots`` robots (default 1000; --quick 50)."""
    count = robots or (50 if quick else 1000)
    seconds = seconds or (2.0 if quick else 6.0)
    if robots_process is None:
        robots_process = count >= ROBOTS_PROCESS_FROM
    raise_fd_limit()
    server = _Server(count, traffic="spread", idle=True) if robots_process else None
    try:
        figures = asyncio.run(
            measure(
                count,
                seconds,
                server=server,
                scrapes=3 if quick else SCRAPES,
                period=0.2 if quick else SCRAPE_PERIOD,
            )
        )
    finally:
        if server is not None:
            server.close()
    where = "fleet_server process, socket://" if robots_process else "in-process sim://"
    extra = {"robots": count, "where": where, "rounds": ROUNDS, "seconds": seconds}
    collector = (figures["followed"] - figures["bare"]) * 1000 / count
    text, om = figures["text"], figures["openmetrics"]

    def ms(values: list[float], q: float) -> float:
        return percentile(values, q) * 1000

    return [
        Row("metrics", f"CPU per robot, followed ({count} robots)",
            figures["followed"] * 100 / count, "% core", figures["bare"] * 100 / count,
            "no collector", extra=extra),
        Row("metrics", "collector's CPU per 1000 robots", collector, "cores"),
        Row("metrics", "RSS per robot followed", figures["rss_per_robot"], "bytes"),
        Row("metrics", "scrape p50, Prometheus text", ms(text, 50), "ms"),
        Row("metrics", "scrape p99, Prometheus text", ms(text, 99), "ms"),
        Row("metrics", "scrape p50, OpenMetrics", ms(om, 50), "ms"),
        Row("metrics", "scrape p99, OpenMetrics", ms(om, 99), "ms"),
        Row("metrics", "CPU of a scrape's read and encoding, Prometheus text",
            figures["text_cpu"] * 1000, "ms"),
        Row("metrics", "CPU of a scrape's read and encoding, OpenMetrics",
            figures["openmetrics_cpu"] * 1000, "ms"),
        Row("metrics", "longest step of a scrape (the loop waits)",
            figures["longest_step"] * 1000, "ms"),
        Row("metrics", "CPU per scrape over HTTP", figures["cpu_per_scrape"] * 1000, "ms"),
        Row("metrics", f"loop lag p99, scraped every {figures['period']:g} s",
            ms(figures["lag_scraped"], 99), "ms", ms(figures["lag_quiet"], 99), "not scraped"),
        Row("metrics", "scrape size, Prometheus text", figures["text_size"] / 1024, "KiB",
            extra={"openmetrics_kib": round(figures["openmetrics_size"] / 1024, 1)}),
    ]  # fmt: skip
