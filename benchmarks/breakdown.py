"""Breakdown: where a fleet's per-frame cost goes, stage by stage, in one process.

N in-process links (a ``Link`` over a ``StreamChannel`` on a null transport, as in ingest)
are fed frames round-robin the way a socket transport feeds them: into the link's read buffer, then
``buffer_updated``; 50 links per event loop turn. Each stage adds one part of the path:

* **read**: the protocol's own work (the decoder returns nothing);
* **decode**: + checking and unpacking the frame (no status built, nothing stored);
* **build**: + building the ``GalileoStatus`` (then dropped);
* **store**: + ``StatusStore.update`` (nobody subscribed);
* **statuses() task**: + a task per link iterating ``statuses()``, as the fleet benchmark's
  driver phase;
* **fleet.statuses()**: store, then instead of a task per link the fleet's listener and
  ONE consumer iterating the merged ``fleet.statuses()`` (compared with **store**).

Each stage runs in a fresh process. Timed: process CPU per frame, the median of the runs.
With ``--instructions`` (needs valgrind): instructions and simulated L2 misses per frame,
from cachegrind runs of two lengths (their difference cancels start-up), exact and
repeatable on a busy machine. A miss means a cache line the frame's path found cold: at a
thousand robots, what one robot's frame touches is evicted by the others' before its next.
"""

from __future__ import annotations

import asyncio
import json
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from .common import Row

__all__ = ["STAGES", "run"]

STAGES = ("read", "decode", "build", "store", "statuses() task", "fleet.statuses()")
#: Stages with their consumers: a task per link, or one merged fleet consumer.
TASK_STAGE, FLEET_STAGE = STAGES[-2], STAGES[-1]
#: Links fed per event loop turn.
BATCH = 50
#: Distinct frames each link is fed in turn.
FRAMES = 200
#: L2 size simulated when the machine does not tell its own.
DEFAULT_L2 = 2 << 20


def _knock_out(stage: str) -> None:
    """Disable the parts of the path after ``stage`` (in this process only)."""
    from galileo_async.protocol import status as decoding
    from galileo_async.state import StatusStore

    # What the stages replace must exist: a renamed one would be measured, not knocked out.
    for owner, name in ((StatusStore, "update"), (decoding, "_V2_BUILD"),
                        (decoding.StatusDecoder, "feed_from")):  # fmt: skip
        if not hasattr(owner, name):
            raise RuntimeError(f"breakdown: {owner.__name__}.{name} is gone; update the stages")
    index = STAGES.index(stage)
    if index < STAGES.index("store"):
        StatusStore.update = lambda self, status: None  # type: ignore[method-assign]
    if index < STAGES.index("build"):
        decoding._V2_BUILD = lambda values: values  # type: ignore[assignment,return-value]
    if index < STAGES.index("decode"):
        decoding.StatusDecoder.feed_from = (  # type: ignore[method-assign]
            lambda self, buffer, size: []
        )


async def _feed(robots: int, frames: list[bytes], consumers: str) -> dict[str, float]:
    """CPU µs per frame for ``robots`` links fed ``frames`` each, and what got where."""
    from galileo_async.state import StatusStore
    from galileo_async.transports import Link, StreamChannel

    from .ingest import null_connector

    protocols: list[Any] = []
    connector = null_connector(protocols)

    links: list[Link] = []
    stores: list[StatusStore] = []
    for _ in range(robots):
        store = StatusStore()
        link = Link(StreamChannel(connector), store, stale_timeout=None, reconnect=False)
        await link.open()
        links.append(link)
        stores.append(store)

    received = [0]

    async def consume(store: StatusStore) -> None:
        async for _status in store.statuses():
            received[0] += 1

    async def consume_fleet() -> None:
        from galileo_async.fleet.streams import FleetHub

        hub = FleetHub()
        for index, store in enumerate(stores):
            hub.attach(str(index), store)
        async for _item in hub.statuses():
            received[0] += 1

    tasks = []
    if consumers == TASK_STAGE:
        tasks = [asyncio.create_task(consume(store)) for store in stores]
    elif consumers == FLEET_STAGE:
        tasks = [asyncio.create_task(consume_fleet())]
    await asyncio.sleep(0)
    reads = [(p.get_buffer(-1), p.buffer_updated) for p in protocols]
    size = len(frames[0])
    start = time.process_time()
    for frame in frames:
        for first in range(0, robots, BATCH):
            for view, updated in reads[first : first + BATCH]:
                view[:size] = frame  # what recv_into does
                updated(size)
            await asyncio.sleep(0)
    elapsed = time.process_time() - start
    for task in tasks:
        task.cancel()
    await asyncio.gather(*tasks, return_exceptions=True)
    for link in links:
        await link.close()
    return {
        "us_per_frame": 1e6 * elapsed / (robots * len(frames)),
        "decoded": sum(link.stats.frames for link in links),
        "stored": sum(store.updates for store in stores),
        "received": received[0],
    }


def _child(stage: str, robots: int, count: int) -> None:
    """One stage in this process: print its figures as JSON."""
    from .ingest import make_frames

    # The same frames however many are fed (cachegrind runs differ in count only); robots
    # on the move, not starting up.
    moving = make_frames(100 + FRAMES)[100:]
    frames = [moving[index % FRAMES] for index in range(count)]
    _knock_out(stage)
    print(json.dumps(asyncio.run(_feed(robots, frames, stage))))


def _spawn(
    stage: str, robots: int, count: int, prefix: list[str] | None = None
) -> dict[str, float]:
    """Run ``stage`` in a child process (under ``prefix``, e.g. valgrind): its figures."""
    env = {**os.environ, "PYTHONHASHSEED": "0"}
    command = [*(prefix or []), sys.executable, "-m", "benchmarks.breakdown",
               stage, str(robots), str(count)]  # fmt: skip
    done = subprocess.run(
        command, capture_output=True, text=True, check=True, env=env, cwd=Path(__file__).parents[1]
    )
    figures: dict[str, float] = json.loads(done.stdout.strip().splitlines()[-1])
    return figures


def _l2_size() -> int:
    try:
        text = Path("/sys/devices/system/cpu/cpu0/cache/index2/size").read_text().strip()
    except OSError:
        return DEFAULT_L2
    match = re.fullmatch(r"(\d+)([KM]?)", text)
    if not match:
        return DEFAULT_L2
    return int(match.group(1)) << {"": 0, "K": 10, "M": 20}[match.group(2)]


def _cachegrind(stage: str, robots: int, count: int, l2: int) -> dict[str, float]:
    """Per-frame cachegrind events of ``stage``: two runs, count and 3 x count frames."""
    totals = []
    with tempfile.TemporaryDirectory() as folder:
        for frames in (count, 3 * count):
            out = Path(folder) / f"cg.{frames}"
            _spawn(stage, robots, frames, [
                "valgrind", "--tool=cachegrind", "--cache-sim=yes", f"--LL={l2},16,64",
                f"--cachegrind-out-file={out}",
            ])  # fmt: skip
            text = out.read_text()
            events = re.search(r"^events: (.*)$", text, re.M)
            summary = re.search(r"^summary: (.*)$", text, re.M)
            if events is None or summary is None:
                raise RuntimeError(f"cachegrind wrote no summary to {out}")
            names, counts = events.group(1).split(), map(int, summary.group(1).split())
            totals.append(dict(zip(names, counts, strict=True)))
    frames = robots * 2 * count
    return {name: (totals[1][name] - totals[0][name]) / frames for name in totals[0]}


def _before(stage: str) -> str | None:
    """The stage ``stage`` adds its part to (both consumer stages build on store)."""
    if stage == FLEET_STAGE:
        return "store"
    index = STAGES.index(stage)
    return STAGES[index - 1] if index else None


def run(*, quick: bool = False, robots: int = 1000, instructions: bool = False) -> list[Row]:
    """Time each stage (and count its instructions and L2 misses when asked)."""
    name = f"breakdown N={robots}"
    repeats, count = (1, 30) if quick else (3, 100)
    times: dict[str, list[float]] = {stage: [] for stage in STAGES}
    for repeat in range(repeats):
        order = STAGES if repeat % 2 == 0 else STAGES[::-1]
        for stage in order:
            times[stage].append(_spawn(stage, robots, count)["us_per_frame"])
    rows = []
    for stage in STAGES:
        value = statistics.median(times[stage])
        before = _before(stage)
        rows.append(Row(name, f"CPU up to {stage}", value, "µs/frame",
                        statistics.median(times[before]) if before else None,
                        before or "", "", None,
                        {"runs": [round(t, 3) for t in times[stage]]}))  # fmt: skip
    if instructions:
        if shutil.which("valgrind") is None:
            print("  valgrind not found: no instruction counts", flush=True)
            return rows
        l2 = _l2_size()
        counted: dict[str, dict[str, float]] = {}
        for stage in STAGES:
            print(f"  cachegrind: {stage} …", flush=True)
            events = counted[stage] = _cachegrind(stage, robots, 5, l2)
            earlier = counted.get(_before(stage) or "")
            rows.append(Row(name, f"instructions up to {stage}", events["Ir"], "per frame",
                            earlier["Ir"] if earlier else None, _before(stage) or ""))  # fmt: skip
            rows.append(Row(name, f"L2 misses up to {stage} (L2 {l2 >> 10} KiB)",
                            events["DLmr"] + events["DLmw"], "per frame",
                            earlier["DLmr"] + earlier["DLmw"] if earlier else None,
                            _before(stage) or ""))  # fmt: skip
    return rows


if __name__ == "__main__":
    _child(sys.argv[1], int(sys.argv[2]), int(sys.argv[3]))
