"""VDA 5050: N vehicles on one event loop, each with its own MQTT session to a real Mosquitto.

Every robot sends 30 status frames/s; each vehicle publishes visualization at 10 Hz. The
robots are in-process ``sim://`` robots, or (``robots_process``, the default from
ROBOTS_PROCESS_FROM vehicles on) simulated robots served by a ``benchmarks.fleet_server``
process (traffic spread over the frame period), each connected here as a ``socket://``
robot. A load driver toggles every robot between teleop forward and stop once a second
(staggered), so ``driving`` flips: a status change that matters.

* **CPU per vehicle**: this process's CPU time over the window / wall time / N (Mosquitto
  and the robots' server run in their own processes and are not counted). Baseline, same
  run: the same N robots and load with no vehicle. **CPU of the adapters**: the
  difference times N, in cores (the robots and the broker not counted). Mosquitto's CPU
  and the robots' server's (``/proc/PID/stat``) are reported beside it, in cores.
* **RSS per vehicle**: this process's resident memory once every vehicle is ONLINE, less
  the same with the robots only (just before the vehicles start), / N.
* **event loop lag**: how late a 10 ms sleep of this loop wakes (p99), with and without
  the vehicles: a loop behind its work, or a process the machine does not run in time,
  shows here before the latencies do.
* **status change → state published**: t0 when the robot records a status whose
  ``driving`` differs from the one before (an update listener); t1 when a master control
  (an aiomqtt client in this process) receives the first state message showing it.
  Baseline, same run: on the same flip a shared client publishes a small message at once,
  t1 when the master receives it (the broker round trip with no adapter). Also: flip →
  the state handed to the vehicle's socket (the adapter's own share), and the vehicles
  again on Mosquitto's default ``set_tcp_nodelay false``, where the broker's Nagle holds
  small messages back.
"""

from __future__ import annotations

import contextlib
import json
import logging
import math
import os
import shutil
import socket
import subprocess
import tempfile
import time
from collections.abc import AsyncIterator, Callable, Iterator
from contextlib import AsyncExitStack
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Any

import aiomqtt
import anyio

import galileo_async
from galileo_async.errors import GalileoError
from galileo_async.models import GalileoStatus
from galileo_async.robot import Robot
from galileo_async.vda5050 import Vehicle, VehicleConfig, run_vehicles
from galileo_async.vda5050.report import driving

from .common import Row, percentile, raise_fd_limit
from .fleet import _connect, _Server

__all__ = ["ROBOTS_PROCESS_FROM", "Broker", "broker", "measure", "mosquitto", "run"]

MOSQUITTO = "/usr/sbin/mosquitto"
#: From this many vehicles on, the robots run in their own process unless told otherwise:
#: 1000 in-process sim robots alone saturate the one core a Python process has.
ROBOTS_PROCESS_FROM = 500
TOGGLE_PERIOD = 1.0
GOAL_P99 = 0.050
#: Issue #33: the adapters of TARGET_N vehicles cost at most GOAL_CORES (pro rata below).
GOAL_CORES = 0.5
TARGET_N = 1000
#: Seconds of the sleep whose oversleep measures the event loop's lag.
LAG_TICK = 0.01
#: This process's cores (CPU time / wall time) from which it counts as saturated.
SATURATED = 0.9
#: Seconds of loop lag (p99) from which the process counts as behind its work.
BEHIND_LAG = 0.1
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


def process_cpu(pid: int) -> float:
    """CPU seconds (user + system) of process ``pid`` so far, from /proc; NaN elsewhere."""
    try:
        with open(f"/proc/{pid}/stat") as stat:
            fields = stat.read().rsplit(")", 1)[1].split()
    except (OSError, IndexError):
        return math.nan
    # Fields 14 and 15 of proc(5) (utime, stime): 12 and 13 after the command's ")".
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


@dataclass(frozen=True)
class Broker:
    """A running Mosquitto: its port on 127.0.0.1 and its process id."""

    port: int
    pid: int


@contextlib.contextmanager
def mosquitto(*, nodelay: bool = True) -> Iterator[int]:
    """A Mosquitto on a free loopback port for the duration; yields the port."""
    with broker(nodelay=nodelay) as running:
        yield running.port


@contextlib.contextmanager
def broker(*, nodelay: bool = True) -> Iterator[Broker]:
    """A Mosquitto on a free loopback port for the duration."""
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
            yield Broker(port, proc.pid)
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
        #: How late a LAG_TICK sleep wakes: the loop's (or the machine's) backlog.
        self.lags: list[float] = []
        #: Toggles the robot's link refused (stale: the process did not read it in time).
        self.refused = 0
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


def _watcher(
    index: int, probe: _Probe, echo: Callable[[int, bool], object] | None
) -> Callable[[GalileoStatus], None]:
    """An update listener that notes each flip of ``driving`` (and echoes it, if asked)."""
    last: bool | None = None

    def listener(status: GalileoStatus) -> None:
        nonlocal last
        value = driving(status)
        if value != last:
            last = value
            probe.flipped(index, value)
            if echo is not None:
                echo(index, value)

    return listener


async def _toggle(robot: Robot, index: int, count: int, probe: _Probe) -> None:
    await anyio.sleep(TOGGLE_PERIOD * index / count)
    while True:
        for command in (partial(robot.forward, 30), robot.zero_speed):
            try:
                await command()
            except GalileoError:  # a starved process: the link went stale meanwhile
                if probe.recording:
                    probe.refused += 1
            await anyio.sleep(TOGGLE_PERIOD / 2)


async def _lag(probe: _Probe) -> None:
    while True:
        start = time.perf_counter()
        await anyio.sleep(LAG_TICK)
        if probe.recording:
            probe.lags.append(time.perf_counter() - start - LAG_TICK)


async def _master(client: aiomqtt.Client, probe: _Probe) -> None:
    async for message in client.messages:
        parts = str(message.topic).split("/")
        body = json.loads(message.payload)  # type: ignore[arg-type]
        if parts[1] == "echo":
            probe.seen(int(parts[2]), body["driving"])
            continue
        probe.seen(int(parts[3][1:]), body["driving"])


@contextlib.asynccontextmanager
async def _robots(count: int, server: _Server | None) -> AsyncIterator[list[Robot]]:
    """``count`` in-process sim robots, or the server's robots connected over ``socket://``."""
    if server is not None:
        robots = await _connect(server)
        try:
            yield robots
        finally:
            with anyio.CancelScope(shield=True):
                for robot in robots:
                    await robot.close()
        return
    async with AsyncExitStack() as stack:
        robots = [
            await stack.enter_async_context(galileo_async.connect("sim://")) for _ in range(count)
        ]
        yield robots


async def measure(
    count: int, seconds: float, port: int, vehicles: bool, *, server: _Server | None = None,
    broker_pid: int | None = None,
) -> dict[str, Any]:  # fmt: skip
    """One phase: ``count`` robots, with vehicles or the bare baseline; CPU and latencies.

    ``server``: the robots are the server's (``socket://``), its CPU measured too;
    ``broker_pid``: Mosquitto's CPU is measured as well (else NaN).
    """
    probe = _Probe(count)
    others = {"server": server.process.pid if server is not None else None,
              "broker": broker_pid}  # fmt: skip
    async with (
        _robots(count, server) as robots,
        aiomqtt.Client("127.0.0.1", port, identifier=f"bench-master-{vehicles}") as master,
        aiomqtt.Client(
            "127.0.0.1", port, identifier=f"bench-echo-{vehicles}", logger=_QUIET
        ) as echo,
        anyio.create_task_group() as group,
    ):
        await master.subscribe(f"{INTERFACE}/v2/bench/+/state")
        await master.subscribe(f"{INTERFACE}/echo/+")
        group.start_soon(_master, master, probe)
        group.start_soon(_lag, probe)
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

        def echo_flip(index: int, value: bool) -> None:
            payload = json.dumps({"driving": value})
            group.start_soon(echo.publish, f"{INTERFACE}/echo/{index}", payload)

        # Listeners, not a task per robot: the baseline's own cost stays small.
        watchers = [_watcher(i, probe, None if vehicles else echo_flip) for i in range(count)]
        for robot, watcher in zip(robots, watchers, strict=True):
            robot.add_update_listener(watcher)
        for index, robot in enumerate(robots):
            group.start_soon(_toggle, robot, index, count, probe)
        await anyio.sleep(2 * TOGGLE_PERIOD)  # warm up
        probe.recording = True
        started = {name: _cpu_of(pid) for name, pid in others.items()}
        cpu, wall = time.process_time(), time.perf_counter()
        await anyio.sleep(seconds)
        cpu, wall = time.process_time() - cpu, time.perf_counter() - wall
        cores = {name: (_cpu_of(pid) - started[name]) / wall for name, pid in others.items()}
        probe.recording = False
        for robot, watcher in zip(robots, watchers, strict=True):
            robot.remove_update_listener(watcher)
        group.cancel_scope.cancel()
    return {
        "cpu_per_robot": cpu / wall / count,
        "server_cores": cores["server"],
        "broker_cores": cores["broker"],
        "latencies": probe.latencies,
        "in_vehicle": probe.in_vehicle,
        "lags": probe.lags,
        "refused": probe.refused,
        "cores": cpu / wall,
        "rss_per_vehicle": rss,
    }


def _cpu_of(pid: int | None) -> float:
    return math.nan if pid is None else process_cpu(pid)


def run(
    *, quick: bool = False, vehicles: int | None = None, seconds: float | None = None,
    robots_process: bool | None = None,
) -> list[Row]:  # fmt: skip
    """Three phases at N vehicles (default 100; --quick 20), each over ``seconds`` (10; 4).

    Baseline and vehicles on a broker with ``set_tcp_nodelay true``, then the vehicles again
    on Mosquitto's default (Nagle on: the broker holds a small message for the ACK of the one
    before, up to the subscriber's delayed ACK). ``robots_process``: the robots in a
    fleet_server process, one for all three phases (default: from ROBOTS_PROCESS_FROM on).
    """
    count = vehicles or (20 if quick else 100)
    seconds = seconds or (4.0 if quick else 10.0)
    if robots_process is None:
        robots_process = count >= ROBOTS_PROCESS_FROM
    raise_fd_limit()
    server = _Server(count, traffic="spread", idle=True) if robots_process else None
    try:
        with broker(nodelay=True) as mqtt:
            phase = partial(measure, count, seconds, mqtt.port, server=server, broker_pid=mqtt.pid)
            bare = anyio.run(phase, False)
            driven = anyio.run(phase, True)
        with broker(nodelay=False) as mqtt:
            phase = partial(measure, count, seconds, mqtt.port, server=server, broker_pid=mqtt.pid)
            nagle = anyio.run(phase, True)
    except FileNotFoundError as exc:
        return [Row("vda5050", f"not run: {exc}", float("nan"), "")]
    finally:
        if server is not None:
            server.close()
    ms = 1000.0
    p99 = percentile(driven["latencies"], 99)
    robots = "fleet_server process, socket://" if robots_process else "in-process sim://"
    extra = {"vehicles": count, "samples": len(driven["latencies"]),
             "baseline_samples": len(bare["latencies"]), "visualization_hz": 10,
             "robots": robots, "process_cores": driven["cores"],
             "baseline_process_cores": bare["cores"],
             "toggles_refused": driven["refused"] + bare["refused"] + nagle["refused"]}  # fmt: skip
    # A process near a whole core, or one the machine did not run in time (its loop
    # lagging), is behind its work: its CPU figures measure what it got, not what it needs.
    lag = max(percentile(driven["lags"], 99), percentile(bare["lags"], 99))
    behind = max(driven["cores"], bare["cores"]) >= SATURATED or lag > BEHIND_LAG

    def latency(name: str, figures: list[float], q: int, **target: Any) -> Row:
        return Row("vda5050", f"{name} p{q}", percentile(figures, q) * ms, "ms",
                   percentile(bare["latencies"], q) * ms, "bare MQTT publish",
                   extra=extra, **target)  # fmt: skip

    change = "status change → state at master"
    adapters = (driven["cpu_per_robot"] - bare["cpu_per_robot"]) * count
    robot = "socket:// robot" if robots_process else "sim robot"
    goal = GOAL_CORES * count / TARGET_N
    return [
        Row("vda5050", f"CPU per vehicle ({count} vehicles)", driven["cpu_per_robot"] * 100,
            "% core", bare["cpu_per_robot"] * 100, f"{robot}, no vehicle", extra=extra),
        Row("vda5050", f"CPU of the {count} adapters (robots, broker not counted)"
            + (", process behind its work: not a measure" if behind else ""), adapters, "cores",
            target=f"≤ {goal:g} cores",
            ok=adapters <= goal if robots_process and not behind else None, extra=extra),
        Row("vda5050", "Mosquitto CPU", driven["broker_cores"], "cores",
            bare["broker_cores"], "no vehicle", extra=extra),
        Row("vda5050", "robots' server CPU", driven["server_cores"], "cores",
            bare["server_cores"], "no vehicle", extra=extra),
        Row("vda5050", "RSS per vehicle", driven["rss_per_vehicle"] / 1024, "KiB",
            extra=extra),
        latency(change, driven["latencies"], 50),
        latency(change, driven["latencies"], 99, target=f"≤ {GOAL_P99 * ms:g} ms",
                ok=p99 <= GOAL_P99),
        latency("status change → state written by the vehicle", driven["in_vehicle"], 99),
        latency(f"{change}, broker Nagle on", nagle["latencies"], 50),
        latency(f"{change}, broker Nagle on", nagle["latencies"], 99),
        Row("vda5050", f"event loop lag p99 (a {LAG_TICK * ms:g} ms sleep wakes late by)",
            percentile(driven["lags"], 99) * ms, "ms", percentile(bare["lags"], 99) * ms,
            "no vehicle", extra=extra),
    ]  # fmt: skip
