"""VDA 5050: N vehicles on one event loop, each with its own MQTT session to a real Mosquitto.

Every robot is an in-process ``sim://`` robot (30 status frames/s); each vehicle publishes
visualization at 10 Hz. A load driver toggles every robot between teleop forward and stop
once a second (staggered), so ``driving`` flips: a status change that matters.

* **CPU per vehicle**: this process's CPU time over the window / wall time / N (Mosquitto
  runs in its own process and is not counted). Baseline, same run: the same N robots and
  load with no vehicle.
* **status change → state published**: t0 when a consumer of ``robot.statuses()`` sees
  ``driving`` flip; t1 when a master control (an aiomqtt client in this process) receives
  the first state message showing the new value. Baseline, same run: on the same flip a
  shared client publishes a small message at once, t1 when the master receives it (the
  broker round trip with no adapter).
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import socket
import subprocess
import tempfile
import time
from collections.abc import AsyncIterator, Iterator
from contextlib import AsyncExitStack
from pathlib import Path
from typing import Any

import aiomqtt
import anyio

import galileo_async
from galileo_async.robot import Robot
from galileo_async.vda5050 import Vehicle, VehicleConfig, run_vehicles
from galileo_async.vda5050.report import driving

from .common import Row, percentile, raise_fd_limit

__all__ = ["measure", "run"]

MOSQUITTO = "/usr/sbin/mosquitto"
TOGGLE_PERIOD = 1.0
GOAL_P99 = 0.050
INTERFACE = "bench"


def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


@contextlib.contextmanager
def mosquitto() -> Iterator[int]:
    """A Mosquitto on a free loopback port for the duration; yields the port."""
    executable = MOSQUITTO if os.access(MOSQUITTO, os.X_OK) else shutil.which("mosquitto")
    if executable is None:
        raise FileNotFoundError("Mosquitto is not installed (.ci/setup installs it)")
    port = _free_port()
    with tempfile.TemporaryDirectory() as directory:
        config = Path(directory) / "mosquitto.conf"
        config.write_text(
            f"listener {port} 127.0.0.1\nallow_anonymous true\npersistence false\n"
            "max_queued_messages 100000\n"
        )
        proc = subprocess.Popen(
            [executable, "-c", str(config)], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
        )
        try:
            deadline = time.monotonic() + 10
            while True:
                try:
                    socket.create_connection(("127.0.0.1", port), timeout=1).close()
                    break
                except OSError:
                    if time.monotonic() > deadline:
                        raise
                    time.sleep(0.05)
            yield port
        finally:
            proc.terminate()
            proc.wait(10)


class _Probe:
    """Flip times per robot and the latencies of their first sighting at the master."""

    def __init__(self, count: int) -> None:
        self.pending: list[tuple[bool, float] | None] = [None] * count
        self.latencies: list[float] = []
        self.recording = False

    def flipped(self, index: int, value: bool) -> None:
        self.pending[index] = (value, time.perf_counter())

    def seen(self, index: int, value: bool) -> None:
        pending = self.pending[index]
        if pending is not None and pending[0] == value:
            if self.recording:
                self.latencies.append(time.perf_counter() - pending[1])
            self.pending[index] = None


async def _watch(robot: Robot, index: int, probe: _Probe, echo: aiomqtt.Client | None) -> None:
    last: bool | None = None
    async for status in robot.statuses():
        value = driving(status)
        if value != last:
            last = value
            probe.flipped(index, value)
            if echo is not None:
                payload = json.dumps({"driving": value})
                await echo.publish(f"{INTERFACE}/echo/{index}", payload)


async def _toggle(robot: Robot, index: int, count: int) -> None:
    await anyio.sleep(TOGGLE_PERIOD * index / count)
    while True:
        await robot.forward(30)
        await anyio.sleep(TOGGLE_PERIOD / 2)
        await robot.stop()
        await anyio.sleep(TOGGLE_PERIOD / 2)


async def _master(client: aiomqtt.Client, probe: _Probe) -> None:
    async for message in client.messages:
        parts = str(message.topic).split("/")
        body = json.loads(message.payload)  # type: ignore[arg-type]
        if parts[1] == "echo":
            probe.seen(int(parts[2]), body["driving"])
            continue
        probe.seen(int(parts[3][1:]), body["driving"])


@contextlib.asynccontextmanager
async def _robots(count: int) -> AsyncIterator[list[Robot]]:
    async with AsyncExitStack() as stack:
        robots = [
            await stack.enter_async_context(galileo_async.connect("sim://")) for _ in range(count)
        ]
        yield robots


async def measure(count: int, seconds: float, port: int, vehicles: bool) -> dict[str, Any]:
    """One phase: ``count`` robots, with vehicles or the bare baseline; CPU and latencies."""
    probe = _Probe(count)
    async with (
        _robots(count) as robots,
        aiomqtt.Client("127.0.0.1", port, identifier=f"bench-master-{vehicles}") as master,
        aiomqtt.Client("127.0.0.1", port, identifier=f"bench-echo-{vehicles}") as echo,
        anyio.create_task_group() as group,
    ):
        await master.subscribe(f"{INTERFACE}/v2/bench/+/state")
        await master.subscribe(f"{INTERFACE}/echo/+")
        group.start_soon(_master, master, probe)
        if vehicles:
            configs = [
                VehicleConfig(
                    broker=f"mqtt://127.0.0.1:{port}",
                    manufacturer="bench",
                    serial_number=f"v{index}",
                    interface_name=INTERFACE,
                )
                for index in range(count)
            ]
            fleet = [Vehicle(r, c) for r, c in zip(robots, configs, strict=True)]
            group.start_soon(run_vehicles, fleet)
            with anyio.fail_after(60):
                for vehicle in fleet:
                    await vehicle.wait_online()
        for index, robot in enumerate(robots):
            group.start_soon(_watch, robot, index, probe, None if vehicles else echo)
            group.start_soon(_toggle, robot, index, count)
        await anyio.sleep(2 * TOGGLE_PERIOD)  # warm up
        probe.recording = True
        cpu, wall = time.process_time(), time.perf_counter()
        await anyio.sleep(seconds)
        cpu, wall = time.process_time() - cpu, time.perf_counter() - wall
        probe.recording = False
        group.cancel_scope.cancel()
    return {"cpu_per_robot": cpu / wall / count, "latencies": probe.latencies}


def run(
    *, quick: bool = False, vehicles: int | None = None, seconds: float | None = None
) -> list[Row]:
    """Both phases at N vehicles (default 100; --quick 20), each over ``seconds`` (10; 4)."""
    count = vehicles or (20 if quick else 100)
    seconds = seconds or (4.0 if quick else 10.0)
    raise_fd_limit()
    try:
        with mosquitto() as port:
            bare = anyio.run(measure, count, seconds, port, False)
            driven = anyio.run(measure, count, seconds, port, True)
    except FileNotFoundError as exc:
        return [Row("vda5050", f"not run: {exc}", float("nan"), "")]
    ms, pct = 1000.0, 100.0
    p99 = percentile(driven["latencies"], 99)
    extra = {"vehicles": count, "samples": len(driven["latencies"]),
             "baseline_samples": len(bare["latencies"]), "visualization_hz": 10}  # fmt: skip
    return [
        Row("vda5050", f"CPU per vehicle ({count} vehicles)", driven["cpu_per_robot"] * pct,
            "% core", bare["cpu_per_robot"] * pct, "sim robot, no vehicle", "", None, extra),
        Row("vda5050", "status change → state published p50",
            percentile(driven["latencies"], 50) * ms, "ms",
            percentile(bare["latencies"], 50) * ms, "bare MQTT publish", "", None, extra),
        Row("vda5050", "status change → state published p99", p99 * ms, "ms",
            percentile(bare["latencies"], 99) * ms, "bare MQTT publish",
            f"≤ {GOAL_P99 * ms:g} ms", p99 <= GOAL_P99, extra),
    ]  # fmt: skip
