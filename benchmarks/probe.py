"""One measurement for ``python -m benchmarks compare``, run in a fresh process per tree.

``python -m benchmarks.probe NAME OPTIONS_JSON`` measures NAME (ingest, fleet or latency;
work runs ingest untimed for cachegrind) with whatever ``galileo_async`` is first on
``sys.path`` and prints, as its last line, a JSON object: the package's file, and every
figure as ``[value, unit]`` (lower is better).

The probes use only the public API (``connect()``, ``Robot``, ``galileo_async.protocol``,
the simulator's wire output) so that one benchmark code runs unchanged against the trees
before and after a restructuring of the package's internals. What the robots send is made
by this checkout's package (the frames file, the fleet server), the same for both trees.
"""

from __future__ import annotations

import asyncio
import contextlib
import gc
import json
import os
import pickle
import shutil
import sys
import tempfile
import time
from collections.abc import Awaitable, Callable
from pathlib import Path
from typing import Any

Figures = dict[str, tuple[float, str]]

__all__ = ["PROBES", "Figures", "make_frames", "measure"]

#: Environment variable naming the PYTHONPATH the fleet server runs with.
SERVER_PATH_ENV = "GALILEO_BENCH_SERVER_PATH"
#: Longest a single awaited step of a probe may take.
STEP_TIMEOUT = 10.0
#: A first status may take this long under cachegrind (about 50x slower) on a loaded machine.
FIRST_STATUS = 120.0


def make_frames(count: int) -> list[bytes]:
    """``count`` v2 frames of a simulated robot driving goals (values change every frame)."""
    from galileo_async.models import StatusLayout
    from galileo_async.protocol import commands as cmd
    from galileo_async.protocol import encode_status
    from galileo_async.sim import RobotModel, SimConfig

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


# --- ingest -------------------------------------------------------------------------------


def _decode(frames: list[bytes], repeats: int) -> float:
    """Best seconds per frame of ``StatusDecoder.feed``, one frame per call."""
    from galileo_async.protocol import StatusDecoder

    best = float("inf")
    for _ in range(repeats):
        decoder = StatusDecoder()
        feed, decoded = decoder.feed, 0
        start = time.perf_counter()
        for chunk in frames:
            decoded += len(feed(chunk))
        best = min(best, (time.perf_counter() - start) / len(frames))
        if decoded != len(frames):
            raise RuntimeError(f"decoded {decoded} of {len(frames)} frames")
    return best


class _Device(asyncio.Protocol):
    """The robot's end of a socket: writes what it is given."""

    def __init__(self, connected: asyncio.Future[asyncio.WriteTransport]) -> None:
        self._connected = connected

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        assert isinstance(transport, asyncio.WriteTransport)
        if not self._connected.done():
            self._connected.set_result(transport)


class _BareHost(asyncio.BufferedProtocol):
    """The control: counts bytes into a buffer of its own, wakes a waiter per frame."""

    def __init__(self, frame_size: int) -> None:
        self._view = memoryview(bytearray(4096))
        self._size = frame_size
        self._bytes = 0
        self._waiter: asyncio.Future[None] | None = None

    def get_buffer(self, sizehint: int) -> memoryview:
        return self._view

    def buffer_updated(self, nbytes: int) -> None:
        self._bytes += nbytes
        self._wake()

    def next_frame(self) -> asyncio.Future[None]:
        """A future that is done once the next whole frame has arrived."""
        self._waiter = asyncio.get_running_loop().create_future()
        self._wake()
        return self._waiter

    def _wake(self) -> None:
        waiter = self._waiter
        if self._bytes >= self._size and waiter is not None and not waiter.done():
            self._bytes -= self._size
            waiter.set_result(None)


async def _ping_pong(
    frames: list[bytes],
    repeats: int,
    connect_host: Callable[[int], Awaitable[tuple[Callable[[int], asyncio.Future[None]], Any]]],
) -> float:
    """Best seconds per frame: the device writes a frame, the host's waiter for it wakes."""
    loop = asyncio.get_running_loop()
    connected: asyncio.Future[asyncio.WriteTransport] = loop.create_future()
    server = await loop.create_server(lambda: _Device(connected), "127.0.0.1", 0)
    port = server.sockets[0].getsockname()[1]
    closers: list[Any] = []
    try:
        host_task = asyncio.ensure_future(connect_host(port))
        device = await asyncio.wait_for(asyncio.shield(connected), STEP_TIMEOUT)
        device.write(frames[0])  # a connect() waits for a first status
        expect, close = await asyncio.wait_for(host_task, STEP_TIMEOUT)
        closers.append(close)
        write, perf = device.write, time.perf_counter
        best = float("inf")
        for _ in range(repeats):
            start = perf()
            for index in range(1, len(frames)):
                arrived = expect(index)
                write(frames[index])
                await arrived
            best = min(best, (perf() - start) / (len(frames) - 1))
            await asyncio.sleep(0.05)  # the next repetition starts on a quiet loop
        return best
    finally:
        for close in closers:
            await close()
        server.close()
        await server.wait_closed()


async def _driver_host(
    port: int, frames: list[bytes], streams: int, waiters: int
) -> tuple[Callable[[int], asyncio.Future[None]], Callable[[], Awaitable[None]]]:
    """A Robot on socket:// with ``streams`` statuses() consumers and ``waiters`` waiters."""
    import galileo_async
    from galileo_async.protocol import StatusDecoder

    # The consumers recognise frame k by its time stamp; repetitions send the frames again.
    stamps = [status.time_stamp for status in StatusDecoder().feed(b"".join(frames))]
    loop = asyncio.get_running_loop()
    wanted: list[Any] = [None, None]  # (time stamp, future)
    robot = await galileo_async.connect(
        f"socket://127.0.0.1:{port}", stale_timeout=None, first_status_timeout=FIRST_STATUS
    )

    async def first(robot: Any) -> None:
        async for status in robot.statuses():
            stamp, future = wanted
            if status.time_stamp == stamp and not future.done():
                future.set_result(None)

    async def other(robot: Any) -> None:
        async for _status in robot.statuses():
            pass

    def never(status: Any) -> bool:
        return bool(status.time_stamp == -1)

    async def wait(robot: Any) -> None:
        await robot.wait_until(never, timeout=3600)

    tasks = [asyncio.create_task(first(robot))]
    tasks += [asyncio.create_task(other(robot)) for _ in range(streams - 1)]
    tasks += [asyncio.create_task(wait(robot)) for _ in range(waiters)]
    await asyncio.sleep(0)

    def expect(index: int) -> asyncio.Future[None]:
        future: asyncio.Future[None] = loop.create_future()
        wanted[:] = [stamps[index], future]
        return future

    async def close() -> None:
        for task in tasks:
            task.cancel()
        await asyncio.gather(*tasks, return_exceptions=True)
        await robot.close()

    return expect, close


async def _bare_host(
    port: int, frame_size: int
) -> tuple[Callable[[int], asyncio.Future[None]], Callable[[], Awaitable[None]]]:
    loop = asyncio.get_running_loop()
    transport, host = await loop.create_connection(lambda: _BareHost(frame_size), "127.0.0.1", port)
    await host.next_frame()  # the first frame

    def expect(index: int) -> asyncio.Future[None]:
        return host.next_frame()

    async def close() -> None:
        transport.close()

    return expect, close


def ingest(options: dict[str, Any]) -> Figures:
    """Decoding, and the full path of a socket:// robot with subscribers, per frame."""
    frames: list[bytes] = pickle.loads(Path(options["frames_file"]).read_bytes())
    repeats = int(options.get("repeats", 5))
    path_frames = frames[: int(options.get("path_frames", 3000))]
    gc.collect()
    us = 1e6
    decode = _decode(frames, repeats)

    def driver(port: int) -> Any:
        return _driver_host(port, path_frames, streams=3, waiters=1)

    def bare(port: int) -> Any:
        return _bare_host(port, len(frames[0]))

    rounds = max(1, repeats // 2)
    full = asyncio.run(_ping_pong(path_frames, rounds, driver))
    control = asyncio.run(_ping_pong(path_frames, rounds, bare))
    return {
        "ingest: decode → GalileoStatus (StatusDecoder.feed), per frame": (decode * us, "µs"),
        "ingest: socket:// frame → 3 statuses() + 1 wait_until, per frame": (full * us, "µs"),
        "ingest: the same, bare BufferedProtocol (control)": (control * us, "µs"),
    }


# --- latency ------------------------------------------------------------------------------


async def _wakeups(
    robot: Any, send: Callable[[int], Awaitable[None]], field: str, samples: int
) -> list[float]:
    """Seconds from the device's send of status k to ``wait_until(field == k)`` returning."""
    latencies: list[float] = []
    perf = time.perf_counter
    for k in range(2, samples + 2):

        def wanted(status: Any, k: int = k) -> bool:
            return bool(getattr(status, field) == k)

        waiter = asyncio.create_task(robot.wait_until(wanted, timeout=STEP_TIMEOUT))
        await asyncio.sleep(0)  # registered before the status is sent
        t0 = perf()
        await send(k)
        await waiter
        latencies.append(perf() - t0)
    return latencies


async def _socket_latency(samples: int) -> tuple[list[float], list[float]]:
    import galileo_async

    from . import latency
    from .latency_loops import Arrivals, timed_commands

    arrivals = Arrivals()
    server, devices = await latency._serve(arrivals)
    port = server.sockets[0].getsockname()[1]

    async def send(k: int) -> None:
        assert devices[-1].transport is not None
        devices[-1].transport.write(latency._frame(k))

    try:
        robot = await galileo_async.connect(
            f"socket://127.0.0.1:{port}", stale_timeout=None, first_status_timeout=FIRST_STATUS
        )
        try:
            status = await _wakeups(robot, send, "time_stamp", samples)
            command = await timed_commands(lambda: robot.forward(20), arrivals, samples // 4)
        finally:
            await robot.close()
    finally:
        server.close()
        await server.wait_closed()
    return status, command


async def _udp_latency(samples: int) -> tuple[list[float], list[float]]:
    import galileo_async

    from . import latency_udp
    from .latency_loops import Arrivals, timed_commands

    arrivals = Arrivals()
    device, port = await latency_udp._device(arrivals)

    async def send(k: int) -> None:
        device.send(latency_udp._frame(k))

    try:
        robot = await galileo_async.connect(f"udp://127.0.0.1:{port}", stale_timeout=None)
        try:
            status = await _wakeups(robot, send, "target_num_id", samples)
            command = await timed_commands(lambda: robot.forward(20), arrivals, samples // 4)
        finally:
            await robot.close()
    finally:
        assert device.transport is not None
        device.transport.close()
    return status, command


async def _http_latency(samples: int) -> tuple[list[float], list[float]]:
    import galileo_async
    from galileo_async.protocol import Velocity

    from . import latency_http
    from .latency_loops import timed_commands

    device = latency_http._Device()
    await device.start()
    try:
        robot = await galileo_async.connect(latency_http._url(device.port), stale_timeout=None)
        try:
            status = await _wakeups(robot, device.send, "target_num_id", samples)
            command = await timed_commands(
                lambda: robot.send(Velocity(0.1, 0.0)), device.arrivals, samples // 4
            )
        finally:
            await robot.close()
    finally:
        await device.stop()
    return status, command


ROS_NODE = Path(__file__).with_name("ros_node.py")
#: Debian's ROS 1 runs under the system interpreter, not the project's venv.
SYSTEM_PYTHON = "/usr/bin/python3"


class NotRun(Exception):
    """A link's peer is missing here: its figures are "not run" rather than numbers."""


def _free_port() -> int:
    import socket

    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


async def _stop(proc: asyncio.subprocess.Process) -> None:
    """Terminate, kill after STEP_TIMEOUT; always reaps."""
    if proc.returncode is None:
        with contextlib.suppress(ProcessLookupError):
            proc.terminate()
        try:
            await asyncio.wait_for(proc.wait(), STEP_TIMEOUT)
        except asyncio.TimeoutError:
            with contextlib.suppress(ProcessLookupError):
                proc.kill()
            await proc.wait()


async def _listening(port: int) -> None:
    """Wait, at most STEP_TIMEOUT, until 127.0.0.1:port accepts connections."""
    deadline = time.monotonic() + STEP_TIMEOUT
    while True:
        try:
            _, writer = await asyncio.open_connection("127.0.0.1", port)
        except OSError:
            if time.monotonic() > deadline:
                raise TimeoutError(f"rosmaster does not listen on 127.0.0.1:{port}") from None
            await asyncio.sleep(0.05)  # another process's port: there is no event to await
            continue
        writer.close()
        return


def _log_file(path: Path) -> Any:
    """The ROS processes' output file (the caller closes it once they have it)."""
    return path.open("ab")


def _tail(path: Path) -> str:
    return path.read_text(errors="replace")[-3000:]


async def _ros_latency(samples: int) -> tuple[list[float], list[float]]:
    """A real rosmaster and benchmarks/ros_node.py (rospy); the driver on ros://.

    Status: the node's time.monotonic() just before ``publish()`` → ``wait_until`` returns.
    Command: ``robot.forward()`` called → the node's rospy callback entered. One clock
    (CLOCK_MONOTONIC) on both sides; the node reports its times after the samples.
    """
    from .latency_loops import COMMAND_GAP

    rosmaster = shutil.which("rosmaster")
    if rosmaster is None or not os.access(SYSTEM_PYTHON, os.X_OK):
        raise NotRun("ROS 1 (rosmaster, rospy) is not installed: run .ci/setup (as root)")
    port = _free_port()
    with tempfile.TemporaryDirectory(prefix="galileo-ros-") as home:
        env = {key: value for key, value in os.environ.items() if not key.startswith("ROS")}
        env.update(ROS_MASTER_URI=f"http://127.0.0.1:{port}/", ROS_IP="127.0.0.1",
                   ROS_HOSTNAME="127.0.0.1", ROS_HOME=home, ROS_LOG_DIR=f"{home}/log",
                   PYTHONDONTWRITEBYTECODE="1")  # fmt: skip
        env.pop("PYTHONPATH", None)
        log_path = Path(home, "processes.log")
        log = _log_file(log_path)
        processes: list[asyncio.subprocess.Process] = []
        try:
            processes.append(await asyncio.create_subprocess_exec(
                rosmaster, "--core", "-p", str(port), stdin=asyncio.subprocess.DEVNULL,
                stdout=log, stderr=log, env=env))  # fmt: skip
            await _listening(port)
            node = await asyncio.create_subprocess_exec(
                SYSTEM_PYTHON, str(ROS_NODE), stdin=asyncio.subprocess.PIPE,
                stdout=asyncio.subprocess.PIPE, stderr=log, env=env)  # fmt: skip
            processes.append(node)
            assert node.stdin is not None
            assert node.stdout is not None
            stdin, stdout = node.stdin, node.stdout
            ready = await asyncio.wait_for(stdout.readline(), STEP_TIMEOUT)
            if not ready.startswith(b"READY"):
                raise RuntimeError(f"the ROS node did not start:\n{_tail(log_path)}")
            robot = await _ros_connect(port, stdin)
            try:
                returned = await _ros_wakeups(robot, stdin, samples)
                called = []
                for _ in range(samples):
                    await asyncio.sleep(COMMAND_GAP)
                    t0 = time.monotonic()
                    await robot.forward(20)
                    called.append(t0)
                stdin.write(f"dump {samples}\n".encode())
                await stdin.drain()
                report = json.loads(await asyncio.wait_for(stdout.readline(), 2 * STEP_TIMEOUT))
            finally:
                await robot.close()
            stdin.write(b"quit\n")
            await stdin.drain()
        finally:
            for proc in reversed(processes):
                await _stop(proc)
            log.close()
    sent = {int(k): t for k, t in report["sent"].items()}
    status = [returned[k] - sent[k] for k in returned]
    seen = [when for when, op in report["commands"] if op == ord("f")]
    if len(seen) != samples:
        raise RuntimeError(f"the ROS node saw {len(seen)} of {samples} forward commands")
    return status, [arrived - t0 for arrived, t0 in zip(seen, called, strict=True)]


async def _ros_connect(port: int, stdin: asyncio.StreamWriter) -> Any:
    """connect() on ros://; the node publishes status 1 every 50 ms until it returns."""
    import galileo_async

    connecting = asyncio.ensure_future(galileo_async.connect(
        f"ros://127.0.0.1:{port}", stale_timeout=None, connect_timeout=STEP_TIMEOUT))  # fmt: skip
    try:
        # The driver's subscription has no event to await: a status once is not enough.
        while not connecting.done():
            stdin.write(b"status 1\n")
            await stdin.drain()
            await asyncio.wait([connecting], timeout=0.05)
    except BaseException:
        connecting.cancel()
        with contextlib.suppress(BaseException):
            robot = await connecting
            await robot.close()
        raise
    return await connecting


async def _ros_wakeups(robot: Any, stdin: asyncio.StreamWriter, samples: int) -> dict[int, float]:
    """The node publishes status k (told on stdin); when ``wait_until(target == k)`` returns."""
    returned: dict[int, float] = {}
    for k in range(2, samples + 2):

        def wanted(status: Any, k: int = k) -> bool:
            return bool(status.target_num_id == k)

        waiter = asyncio.create_task(robot.wait_until(wanted, timeout=STEP_TIMEOUT))
        await asyncio.sleep(0)  # registered before the status is published
        stdin.write(f"status {k}\n".encode())
        await stdin.drain()
        await waiter
        returned[k] = time.monotonic()
    return returned


#: The link kinds latency covers: (URL scheme, status path, command path, measurement).
LINKS: tuple[tuple[str, str, str, Callable[[int], Any]], ...] = (
    ("socket://", "status frame → wait_until", "robot.forward() → bytes at device",
     _socket_latency),
    ("udp://", "status datagram → wait_until", "robot.forward() → datagram at device",
     _udp_latency),
    ("http://", "WebSocket status → wait_until", "send(Velocity) → PUT at device", _http_latency),
    ("ros://", "status published → wait_until", "robot.forward() → rospy callback at node",
     _ros_latency),
)  # fmt: skip


def latency(options: dict[str, Any]) -> Figures:
    """Status → waiter and command → device, p50 and p99, on every link kind of LINKS.

    ros:// takes ``ros_samples`` of each (its commands are COMMAND_GAP apart); a link whose
    peer is missing gives one figure, "latency SCHEME not run: why", with no value.
    """
    from .common import percentile

    samples = int(options.get("samples", 2000))
    figures: Figures = {}
    ms = 1000
    for scheme, status_path, command_path, measure_link in LINKS:
        try:
            if scheme == "ros://":
                status, command = asyncio.run(measure_link(int(options.get("ros_samples", 300))))
            else:
                status, command = asyncio.run(measure_link(samples))
        except NotRun as exc:
            figures[f"latency {scheme} not run: {exc}"] = (float("nan"), "")
            continue
        for q in (50, 99):
            figures[f"latency {scheme} {status_path} p{q}"] = (percentile(status, q) * ms, "ms")
        for q in (50, 99):
            figures[f"latency {scheme} {command_path} p{q}"] = (percentile(command, q) * ms, "ms")
    return figures


# --- fleet --------------------------------------------------------------------------------


async def _fleet(
    count: int,
    seconds: float,
    warmups: tuple[float, float],
    server_path: str | None,
    expected: Path,
) -> Figures:
    """The fleet's figures; the server runs ``server_path``'s package, found at ``expected``.

    ``warmups``: seconds before the first phase, and before each phase's window.
    """
    import galileo_async

    from . import fleet

    env = None if server_path is None else {**os.environ, "PYTHONPATH": server_path}
    server = fleet._Server(count, env=env)
    server_warmup, warmup = warmups
    if server_path is not None and not Path(server.info["package"]).is_relative_to(expected):
        server.close()
        raise RuntimeError(f"the fleet server ran {server.info['package']}, not {expected}")
    loop = asyncio.get_running_loop()

    async def window() -> tuple[float, int, float]:
        """(driver CPU s, frames the server sent, wall s) over ``seconds``."""
        before = await loop.run_in_executor(None, server.cpu)
        cpu0, wall0 = time.process_time(), time.perf_counter()
        await asyncio.sleep(seconds)
        cpu, wall = time.process_time() - cpu0, time.perf_counter() - wall0
        after = await loop.run_in_executor(None, server.cpu)
        return cpu, after["frames_sent"] - before["frames_sent"], wall

    async def robots_phase(tasks_per_robot: bool) -> tuple[float, int, float, list[float]]:
        robots: list[Any] = []
        ages: list[float] = []
        recording = False
        origin, period = server.origin, server.period
        every = max(1, count // fleet.AGE_ROBOTS)

        async def consume(robot: Any, timed: bool) -> None:
            async for status in robot.statuses():
                if timed and recording:
                    ages.append(time.monotonic() - (origin + status.time_stamp * period))

        async def sample() -> None:
            while True:
                await asyncio.sleep(1 / fleet.SAMPLE_RATE)
                for robot in robots:
                    _ = robot.status

        try:
            for start in range(0, count, fleet.CONNECT_BATCH):
                batch = server.ports[start : start + fleet.CONNECT_BATCH]
                robots += await asyncio.gather(
                    *(galileo_async.connect(f"socket://127.0.0.1:{port}") for port in batch)
                )
            if tasks_per_robot:
                tasks = [asyncio.create_task(consume(robot, index % every == 0))
                         for index, robot in enumerate(robots)]  # fmt: skip
            else:
                tasks = [asyncio.create_task(sample())]
            try:
                await asyncio.sleep(warmup)
                recording = True
                cpu, frames, wall = await window()
                recording = False
            finally:
                for task in tasks:
                    task.cancel()
                await asyncio.gather(*tasks, return_exceptions=True)
        finally:
            await asyncio.gather(*(robot.close() for robot in robots), return_exceptions=True)
        return cpu, frames, wall, ages

    try:
        await fleet._bare(server, server_warmup, warmup=0)  # untimed: warms both processes up
        bare = await fleet._bare(server, seconds, warmup=warmup)
        task_cpu, task_frames, _wall, ages = await robots_phase(tasks_per_robot=True)
        sampled_cpu, sampled_frames, _wall, _ = await robots_phase(tasks_per_robot=False)
    finally:
        await loop.run_in_executor(None, server.close)
    us = 1e6
    bare_us = us * bare.cpu / max(1, bare.frames)
    task_us = us * task_cpu / max(1, task_frames)
    sampled_us = us * sampled_cpu / max(1, sampled_frames)
    from .common import percentile

    name = f"fleet N={count}"
    return {
        f"{name}: driver, a statuses() task per robot, CPU per frame": (task_us, "µs"),
        f"{name}: driver, no task (sampled), CPU per frame": (sampled_us, "µs"),
        f"{name}: bare asyncio.Protocol (control), CPU per frame": (bare_us, "µs"),
        f"{name}: task per robot / bare, same round": (task_us / bare_us, "×"),
        f"{name}: sampled / bare, same round": (sampled_us / bare_us, "×"),
        f"{name}: status age p99, task per robot": (percentile(ages, 99) * 1000, "ms"),
    }


def fleet_probe(options: dict[str, Any]) -> Figures:
    """The fleet at N robots: driver CPU per frame with and without tasks, next to bare."""
    from .common import pin_malloc, raise_fd_limit

    raise_fd_limit()
    pin_malloc()
    from . import fleet

    count, seconds = int(options.get("fleet", 1000)), float(options.get("seconds", 6))
    warmups = (float(options.get("server_warmup", fleet.SERVER_WARMUP)),
               float(options.get("warmup", fleet.WARMUP)))  # fmt: skip
    server_path = os.environ.get(SERVER_PATH_ENV)
    expected = Path(server_path or ".", "galileo_async").resolve()
    return asyncio.run(_fleet(count, seconds, warmups, server_path, expected))


def work(options: dict[str, Any]) -> Figures:
    """Ingest's work, untimed, for an instruction count: ``part`` decode or path, ``count``."""
    frames: list[bytes] = pickle.loads(Path(options["frames_file"]).read_bytes())
    frames = frames[: int(options["count"])]
    if options["part"] == "decode":
        _decode(frames, 1)
    else:

        def driver(port: int) -> Any:
            return _driver_host(port, frames, streams=3, waiters=1)

        asyncio.run(_ping_pong(frames, 1, driver))
    return {}


PROBES: dict[str, Callable[[dict[str, Any]], Figures]] = {
    "ingest": ingest,
    "fleet": fleet_probe,
    "latency": latency,
    "work": work,
}


def measure(name: str, options: dict[str, Any]) -> dict[str, Any]:
    """Run probe ``name``; the package it measured and its figures."""
    import galileo_async

    figures = PROBES[name](options)
    return {
        "package": os.path.realpath(galileo_async.__file__),
        "figures": {key: [value, unit] for key, (value, unit) in figures.items()},
    }


def main(argv: list[str] | None = None) -> int:
    """``python -m benchmarks.probe NAME OPTIONS_JSON``: print the figures as JSON."""
    args = sys.argv[1:] if argv is None else argv
    name, options = args[0], json.loads(args[1]) if len(args) > 1 else {}
    print(json.dumps(measure(name, options)), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
