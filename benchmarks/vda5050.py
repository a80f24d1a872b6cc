"""VDA 5050: N vehicles on one event loop, each with its own MQTT session to a real Mosquitto.

Every robot is an in-process ``sim://`` robot (30 status frames/s); each vehicle publishes
visualization at 10 Hz. A load driver toggles every robot between teleop forward and stop
once a second (staggered), so ``driving`` flips: a status change that matters.

* **CPU per vehicle**: this process's CPU time over the window / wall time / N (Mosquitto
  runs in its own process and is not counted). Baseline, same run: the same N robots and
  load with no vehicle. **CPU of the adapters**: the difference times N, in cores (the
  robots and the broker not counted).
* **RSS per vehicle**: this process's resident memory once every vehicle is ONLINE, less
  the same with the robots only (just before the vehicles start), / N.
* **status change → state published**: t0 when a consumer of ``robot.statuses()`` sees
  ``driving`` flip; t1 when a master control (an aiomqtt client in this process) receives
  the first state message showing the new value. Baseline, same run: on the same flip a
  shared client publishes a small message at once, t1 when the master receives it (the
  broker round trip with no adapter). Also: flip → the state handed to the vehicle's socket
  (the adapter's own share), and the vehicles again on Mosquitto's default
  ``set_tcp_nodelay false``, where the broker's Nagle holds small messages back.
"""

from __future__ import annotations

import contextlib
import json
import logging
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
#: The shared baseline client has many publishes in flight at once, which aiomqtt logs.
_QUIET = logging.getLogger("benchmarks.vda5050.echo")
_QUIET.setLevel(logging.ERROR)


def _rss() -> int:
    """This process's resident set size in bytes (Linux /proc; 0 elsewhere)."""
    try:
        with open("/proc/self/statm") as statm:
            return int(statm.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, IndexError):
        return 0


def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


@contextlib.contextmanager
def mosquitto(*, nodelay: bool = True) -> Iterator[int]:
    """A Mosquitto on a free loopback port for the duration; yields the port."""
    executable = MOSQUITTO if os.access(MOSQUITTO, os.X_OK) else shutil.which("mosquitto")
    if executable is None:
        raise FileNotFoundError("Mosquitto is not installed (.ci/setup installs it)")
    port = _free_port()
    with tempfile.TemporaryDirectory() as directory:
        config = Path(directory) / "mosquitto.conf"
        config.write_text(
            f"listener {port} 127.0.0.1\nallow_anonymous true\npersistence false\n"
            f"max_queued_messages 100000\nset_tcp_nodelay {str(nodelay).lower()}\n"
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
        #: Flip → the state handed to the vehicle's socket (the adapter's own share).
        self.in_vehicle: list[float] = []
        self.written: dict[int, float] = {}
        self.recording = False

    def flipped(self, index: int, value: bool) -> None:
        self.pending[index] = (value, time.perf_counter())

    def seen(self, index: int, value: bool) -> None:
        pending = self.pending[index]
        if pending is not None and pending[0] == value:
            if self.recording:
                self.latencies.append(time.perf_counter() - pending[1])
                written = self.written.get(index)
                if written is not None and written >= pending[1]:
                    self.in_vehicle.append(written - pending[1])
            self.pending[index] = None


class _TimedVehicle(Vehicle):
    """A Vehicle that notes when each state message has been handed to its socket."""

    def __init__(self, robot: Robot, config: VehicleConfig, index: int, probe: _Probe) -> None:
        super().__init__(robot, config)
        self._index, self._probe = index, probe

    async def publish_state(self) -> None:
        await super().publish_state()
        self._probe.written[self._index] = time.perf_counter()


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
        await robot.zero_speed()
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
        aiomqtt.Client(
            "127.0.0.1", port, identifier=f"bench-echo-{vehicles}", logger=_QUIET
        ) as echo,
        anyio.create_task_group() as group,
    ):
        await master.subscribe(f"{INTERFACE}/v2/bench/+/state")
        await master.subscribe(f"{INTERFACE}/echo/+")
        group.start_soon(_master, master, probe)
        rss = 0.0
        if vehicles:
            before = _rss()
            configs = [
                VehicleConfig(
                    broker=f"mqtt://127.0.0.1:{port}",
                    manufacturer="bench",
                    serial_number=f"v{index}",
                    interface_name=INTERFACE,
                )
                for index in range(count)
            ]
            fleet = [
                _TimedVehicle(robot, config, index, probe)
                for index, (robot, config) in enumerate(zip(robots, configs, strict=True))
            ]
            group.start_soon(run_vehicles, fleet)
            with anyio.fail_after(60 + count / 10):
                for vehicle in fleet:
                    await vehicle.wait_online()
            rss = (_rss() - before) / count
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
    return {
        "cpu_per_robot": cpu / wall / count,
        "latencies": probe.latencies,
        "in_vehicle": probe.in_vehicle,
        "rss_per_vehicle": rss,
    }


def run(
    *, quick: bool = False, vehicles: int | None = None, seconds: float | None = None
) -> list[Row]:
    """Three phases at N vehicles (default 100; --quick 20), each over ``seconds`` (10; 4).

    Baseline and vehicles on a broker with ``set_tcp_nodelay true``, then the vehicles again
    on Mosquitto's default (Nagle on: the broker holds a small message for the ACK of the one
    before, up to the subscriber's delayed ACK).
    """
    count = vehicles or (20 if quick else 100)
    seconds = seconds or (4.0 if quick else 10.0)
    raise_fd_limit()
    try:
        with mosquitto(nodelay=True) as port:
            bare = anyio.run(measure, count, seconds, port, False)
            driven = anyio.run(measure, count, seconds, port, True)
        with mosquitto(nodelay=False) as port:
            nagle = anyio.run(measure, count, seconds, port, True)
    except FileNotFoundError as exc:
        return [Row("vda5050", f"not run: {exc}", float("nan"), "")]
    ms = 1000.0
    p99 = percentile(driven["latencies"], 99)
    extra = {"vehicles": count, "samples": len(driven["latencies"]),
             "baseline_samples": len(bare["latencies"]), "visualization_hz": 10}  # fmt: skip

    def latency(name: str, figures: list[float], q: int, **target: Any) -> Row:
        return Row("vda5050", f"{name} p{q}", percentile(figures, q) * ms, "ms",
                   percentile(bare["latencies"], q) * ms, "bare MQTT publish",
                   extra=extra, **target)  # fmt: skip

    change = "status change → state at master"
    adapters = (driven["cpu_per_robot"] - bare["cpu_per_robot"]) * count
    return [
        Row("vda5050", f"CPU per vehicle ({count} vehicles)", driven["cpu_per_robot"] * 100,
            "% core", bare["cpu_per_robot"] * 100, "sim robot, no vehicle", extra=extra),
        Row("vda5050", f"CPU of the {count} adapters (robots, broker not counted)", adapters,
            "cores", extra=extra),
        Row("vda5050", "RSS per vehicle", driven["rss_per_vehicle"] / 1024, "KiB",
            extra=extra),
        latency(change, driven["latencies"], 50),
        latency(change, driven["latencies"], 99, target=f"≤ {GOAL_P99 * ms:g} ms",
                ok=p99 <= GOAL_P99),
        latency("status change → state written by the vehicle", driven["in_vehicle"], 99),
        latency(f"{change}, broker Nagle on", nagle["latencies"], 50),
        latency(f"{change}, broker Nagle on", nagle["latencies"], 99),
    ]  # fmt: skip
