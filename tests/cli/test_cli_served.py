"""The CLI against a simulator that outlives one command: served over TCP or a pty."""

from __future__ import annotations

import asyncio
import concurrent.futures
import contextlib
import json
import os
import select
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Coroutine, Iterator
from pathlib import Path
from typing import IO, Any, TypeVar

import pytest
from typer.testing import CliRunner, Result

from galileo_async.cli import ExitCode, app
from galileo_async.models import TargetStatus
from galileo_async.sim import SimState, Simulator

_T = TypeVar("_T")

#: Bound on every wait in this module, seconds.
WAIT = 15.0
GALILEO = [sys.executable, "-m", "galileo_async"]


class ServedSim:
    """A simulator on 127.0.0.1 run by its own event loop in a thread, so CLI runs can share it."""

    def __init__(self, **config: Any) -> None:
        self.loop = asyncio.new_event_loop()
        self.simulator: Simulator | None = None
        self.url = ""
        self._ready = threading.Event()
        self._thread = threading.Thread(target=self._run, args=(config,), daemon=True)
        self._thread.start()
        assert self._ready.wait(WAIT), "the simulator thread did not start"

    def _run(self, config: dict[str, Any]) -> None:
        asyncio.set_event_loop(self.loop)
        self.loop.run_until_complete(self._serve(config))
        self._ready.set()
        self.loop.run_forever()

    async def _serve(self, config: dict[str, Any]) -> None:
        self.simulator = Simulator(**config)
        server = await self.simulator.serve_tcp("127.0.0.1", 0)
        self.url = f"socket://127.0.0.1:{server.sockets[0].getsockname()[1]}"

    @property
    def state(self) -> SimState:
        assert self.simulator is not None
        return self.simulator.state

    def wait_for(self, predicate: Callable[[SimState], bool], timeout: float = WAIT) -> None:
        """Wait (checking on the simulator's own loop after every tick) until predicate holds."""

        async def check() -> None:
            # The simulator has no change notification: look again after each frame or so.
            while not predicate(self.state):  # noqa: ASYNC110
                await asyncio.sleep(0.005)

        future = asyncio.run_coroutine_threadsafe(asyncio.wait_for(check(), timeout), self.loop)
        future.result(timeout + 1)

    def run_soon(self, coroutine: Coroutine[Any, Any, _T]) -> concurrent.futures.Future[_T]:
        """Run ``coroutine`` on the simulator's loop; its future for the test thread."""
        return asyncio.run_coroutine_threadsafe(coroutine, self.loop)

    def stop_serving(self) -> None:
        """Close the simulator (its server and every connection), leaving the loop running."""
        assert self.simulator is not None
        self.run_soon(self.simulator.close()).result(WAIT)

    def close(self) -> None:
        self.stop_serving()  # Simulator.close is idempotent
        self.loop.call_soon_threadsafe(self.loop.stop)
        self._thread.join(WAIT)
        self.loop.close()


class HttpServedSim(ServedSim):
    """The simulator's HTTP face on 127.0.0.1 (REST and WebSocket), on its own thread's loop."""

    async def _serve(self, config: dict[str, Any]) -> None:
        self.simulator = Simulator(**config)
        face = await self.simulator.serve_http()
        self.url = f"http://127.0.0.1:{face.address[1]}?ws_port={face.ws_address[1]}"


def serving(speed: float) -> Iterator[ServedSim]:
    """A ServedSim at ``speed`` for a fixture's life: ``yield from serving(5.0)``."""
    sim = ServedSim(speed=speed)
    try:
        yield sim
    finally:
        sim.close()


@pytest.fixture
def served() -> Iterator[ServedSim]:
    yield from serving(5.0)


def invoke(url: str, *args: str) -> Result:
    env = {"GALILEO_PORT": None, "COLUMNS": "120"}
    return CliRunner().invoke(app, ["--port", url, *args], env=env)


def ok(url: str, *args: str) -> Result:
    result = invoke(url, *args)
    assert result.exit_code == 0, (args, result.output)
    return result


def working(state: SimState) -> bool:
    return state.status.target_status == TargetStatus.WORKING


def test_nav_goal_pause_resume_cancel_on_one_robot(served: ServedSim) -> None:
    ok(served.url, "nav", "start")
    assert served.state.status.navigating
    ok(served.url, "send", "Goto", "1")
    served.wait_for(working)
    assert "goal paused" in ok(served.url, "pause").stdout
    assert served.state.status.target_status == TargetStatus.PAUSED
    assert "goal resumed" in ok(served.url, "resume").stdout
    assert working(served.state)
    ok(served.url, "cancel")
    assert served.state.status.target_num_id == -1
    assert not served.state.status.goal_active


def test_patrol_map_charge_and_shutdown_on_one_robot(served: ServedSim) -> None:
    ok(served.url, "nav", "start")
    ok(served.url, "patrol", "start", "--dwell", "4")
    assert served.state.status.patrolling
    assert served.state.patrol_dwell == 4
    ok(served.url, "patrol", "stop")
    assert not served.state.status.patrolling
    assert served.state.status.navigating
    ok(served.url, "nav", "stop")
    ok(served.url, "map", "start")
    assert served.state.status.mapping
    ok(served.url, "map", "save")
    ok(served.url, "map", "update")
    ok(served.url, "map", "stop")
    assert not served.state.status.mapping
    ok(served.url, "charge", "save-dock")
    ok(served.url, "charge", "start")
    ok(served.url, "charge", "stop")
    assert not served.state.status.charging
    ok(served.url, "shutdown", "--yes")
    served.wait_for(lambda state: state.shutdown)


@contextlib.contextmanager
def goto_in_background(served: ServedSim, target_id: int) -> Iterator[subprocess.Popen[str]]:
    """``galileo goto`` in a child process, once the simulator shows the goal working."""
    ok(served.url, "nav", "start")
    goto = subprocess.Popen(
        [*GALILEO, "--port", served.url, "goto", str(target_id)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        served.wait_for(working)
        yield goto
    finally:
        goto.kill()
        goto.communicate()


def test_goto_cancelled_from_elsewhere_exits_with_cancelled(served: ServedSim) -> None:
    with goto_in_background(served, 1) as goto:
        ok(served.url, "cancel")
        assert goto.wait(WAIT) == ExitCode.CANCELLED
        assert goto.stderr is not None
        assert "GoalCancelled" in goto.stderr.read()


def test_goto_preempted_by_another_goal_exits_with_cancelled(served: ServedSim) -> None:
    with goto_in_background(served, 1) as goto:
        ok(served.url, "send", "Goto", "2")
        assert goto.wait(WAIT) == ExitCode.CANCELLED
        served.wait_for(lambda state: state.status.target_num_id == 2)


def test_goto_interrupted_sends_cancel(served: ServedSim) -> None:
    with goto_in_background(served, 1) as goto:
        goto.send_signal(signal.SIGINT)
        assert goto.wait(WAIT) == ExitCode.INTERRUPTED
        served.wait_for(lambda state: not state.status.goal_active)  # i 2 sent on the way out


def test_monitor_shows_the_events_of_a_goal(served: ServedSim) -> None:
    monitor = subprocess.Popen(
        [*GALILEO, "--json", "--port", served.url, "monitor", "--duration", str(WAIT)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert monitor.stdout is not None
        seen: list[dict[str, Any]] = []

        def read_until(name: str) -> None:
            deadline = time.monotonic() + WAIT
            while not any(line.get("event") == name or name in line for line in seen):
                ready, _, _ = select.select([monitor.stdout], [], [], deadline - time.monotonic())
                assert ready, f"no {name} in {seen}"
                seen.append(json.loads(monitor.stdout.readline()))

        read_until("status")  # subscribed: the first snapshot is out
        assert "arrived at target 0" in ok(served.url, "goto", "0", "--start-nav").stdout
        read_until("GoalReached")
        names = [line.get("event") for line in seen]
        for name in ("NavigationOpened", "VisualInitialised", "GoalAccepted"):
            assert name in names
        reached = next(line for line in seen if line.get("event") == "GoalReached")
        assert reached["target_id"] == 0
    finally:
        monitor.kill()
        monitor.communicate()


def _read_until(stream: IO[str], text: str, timeout: float = WAIT) -> str:
    """Lines read from ``stream`` until one contains ``text`` (failing after ``timeout``)."""
    deadline = time.monotonic() + timeout
    seen = ""
    while text not in seen:
        ready, _, _ = select.select([stream], [], [], max(0.0, deadline - time.monotonic()))
        assert ready, f"{text!r} not seen in {seen!r}"
        line = stream.readline()
        assert line, f"the stream ended before {text!r}: {seen!r}"
        seen += line
    return seen


def _watch(served: ServedSim, *args: str) -> subprocess.Popen[str]:
    """``galileo status --watch`` on the served robot, once its first line is out."""
    watch = subprocess.Popen(
        [*GALILEO, "--port", served.url, "status", "--watch", "--interval", "0.05", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    assert watch.stdout is not None
    _read_until(watch.stdout, "nav ")
    return watch


def test_status_watch_exits_when_the_server_goes_away_without_reconnect(
    served: ServedSim,
) -> None:
    watch = _watch(served, "--no-reconnect")
    try:
        served.stop_serving()
        assert watch.wait(WAIT) == ExitCode.CONNECTION
        assert watch.stderr is not None
        stderr = watch.stderr.read()
        assert "connection lost" in stderr
        assert stderr.strip().splitlines()[-1].startswith("error: ConnectionLost: ")
    finally:
        watch.kill()
        watch.communicate()


def test_status_watch_says_when_the_server_goes_away(served: ServedSim) -> None:
    watch = _watch(served)
    try:
        served.stop_serving()
        assert watch.stderr is not None
        lost = _read_until(watch.stderr, "connection lost").splitlines()[-1]
        assert lost.endswith("; reconnecting…")
        assert watch.poll() is None  # still waiting for the robot to come back
    finally:
        watch.kill()
        watch.communicate()


def test_monitor_json_says_when_the_server_goes_away(served: ServedSim) -> None:
    monitor = subprocess.Popen(
        [*GALILEO, "--json", "--port", served.url, "monitor", "--duration", str(WAIT)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert monitor.stdout is not None
        _read_until(monitor.stdout, '"status"')
        served.stop_serving()
        lost = _read_until(monitor.stdout, '"ConnectionLost"').splitlines()[-1]
        assert json.loads(lost)["reason"]
    finally:
        monitor.kill()
        monitor.communicate()


def _start_sim(*args: str) -> tuple[subprocess.Popen[str], str]:
    process = subprocess.Popen(
        [*GALILEO, "sim", *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    assert process.stdout is not None
    ready, _, _ = select.select([process.stdout], [], [], WAIT)
    assert ready, "galileo sim printed nothing"
    return process, process.stdout.readline().strip()


def _stop_sim(process: subprocess.Popen[str]) -> None:
    process.send_signal(signal.SIGINT)
    try:
        assert process.wait(WAIT) == 0
    finally:
        process.kill()
        process.communicate()


def test_sim_tcp_subprocess_serves_a_robot(tmp_path: Path) -> None:
    process, url = _start_sim(
        "--tcp", "127.0.0.1:0", "--speed", "20", "--layout", "v1_charge", "--options", "garbage=0.3"
    )
    try:
        assert url.startswith("socket://127.0.0.1:")
        status = ok(url, "status", "--json").stdout
        assert '"layout": "v1_charge"' in status
        assert "arrived at target 3" in ok(url, "goto", "3", "--start-nav").stdout
        capture = tmp_path / "over-tcp.glc"
        ok(url, "record", str(capture), "--duration", "0.3")
        summary = json.loads(ok(url, "decode", str(capture), "--json").stdout.splitlines()[-1])
        assert summary["summary"]["layout"] == "v1_charge"
        assert summary["summary"]["bytes_discarded"] > 0  # the garbage option reached the sim
    finally:
        _stop_sim(process)


def test_sim_tcp_document_firmware_handles_rotate() -> None:
    process, url = _start_sim("--tcp", "127.0.0.1:0", "--speed", "20", "--firmware", "document")
    try:
        ok(url, "nav", "start")
        assert "rotated to 45°" in ok(url, "rotate", "45").stdout
    finally:
        _stop_sim(process)


@pytest.mark.skipif(not hasattr(os, "openpty"), reason="needs a POSIX pty")
def test_sim_pty_subprocess_serves_a_robot() -> None:
    process, path = _start_sim("--pty", "--speed", "20", "--layout", "v2_truncated")
    try:
        assert path.startswith("/dev/")
        status = ok(path, "status", "--json").stdout
        assert '"layout": "v2_truncated"' in status
    finally:
        _stop_sim(process)


def test_sim_rejects_tcp_and_pty_together() -> None:
    result = CliRunner().invoke(app, ["sim", "--pty", "--tcp", "127.0.0.1:0"])
    assert result.exit_code == ExitCode.USAGE


class Terminal:
    """A child process whose stdin and stdout are the slave side of a pty."""

    def __init__(self, args: list[str]) -> None:
        self.master, slave = os.openpty()
        env = dict(os.environ, COLUMNS="100", TERM="xterm")
        self.process = subprocess.Popen(
            args, stdin=slave, stdout=slave, stderr=slave, env=env, close_fds=True
        )
        os.close(slave)
        self.output = b""

    def expect(self, text: bytes, timeout: float = WAIT) -> None:
        deadline = time.monotonic() + timeout
        while text not in self.output:
            left = deadline - time.monotonic()
            assert left > 0, f"{text!r} not seen in {self.output!r}"
            ready, _, _ = select.select([self.master], [], [], left)
            if ready:
                try:
                    chunk = os.read(self.master, 4096)
                except OSError:  # EIO: the child closed the terminal
                    chunk = b""
                assert chunk, f"terminal closed before {text!r}: {self.output!r}"
                self.output += chunk

    def send(self, keys: bytes) -> None:
        os.write(self.master, keys)

    def close(self) -> None:
        self.process.kill()
        self.process.wait(WAIT)
        os.close(self.master)


@pytest.mark.skipif(not hasattr(os, "openpty"), reason="needs a POSIX pty")
def test_teleop_under_a_pty(served: ServedSim) -> None:
    terminal = Terminal([*GALILEO, "--port", served.url, "teleop", "--speed", "50"])
    try:
        terminal.expect(b"q quit")
        terminal.send(b"w")
        terminal.expect(b"forward 50%")
        served.wait_for(lambda state: (state.status.current_speed_x or 0.0) > 0.1)
        terminal.send(b" ")
        terminal.expect(b"stop\r\n")
        served.wait_for(lambda state: state.status.current_speed_x == 0.0)
        terminal.send(b"+\x1b[D")  # faster, then the left arrow
        terminal.expect(b"left 60%")
        served.wait_for(lambda state: (state.status.current_speed_theta or 0.0) > 0.1)
        terminal.send(b"\x1b")  # an escape sequence split across two reads
        terminal.send(b"[C")
        terminal.expect(b"right 60%")
        terminal.send(b"q")
        terminal.expect(b"stop (on exit)")
        assert terminal.process.wait(WAIT) == 0
        served.wait_for(lambda state: state.status.current_speed_theta == 0.0)
    finally:
        terminal.close()


@pytest.mark.skipif(not hasattr(os, "openpty"), reason="needs a POSIX pty")
def test_teleop_keeps_a_held_key_alive_and_stops_on_release(served: ServedSim) -> None:
    terminal = Terminal([*GALILEO, "--port", served.url, "teleop", "--speed", "50"])
    try:
        terminal.expect(b"q quit")
        for _ in range(15):  # a held key: the terminal repeats it, here every 0.1 s
            terminal.send(b"w")
            time.sleep(0.1)
        assert served.state.status.control_speed_x == pytest.approx(0.4, abs=1e-3)
        released = time.monotonic()
        served.wait_for(lambda state: state.status.current_speed_x == 0.0)
        assert time.monotonic() - released < 1.0  # 0.5 s without a repeat, then the stop
        terminal.expect(b"released: stop")
        terminal.send(b"q")
        terminal.expect(b"stop (on exit)")
        assert terminal.process.wait(WAIT) == 0
    finally:
        terminal.close()


@pytest.mark.skipif(not hasattr(os, "openpty"), reason="needs a POSIX pty")
def test_teleop_sends_stop_when_interrupted(served: ServedSim) -> None:
    terminal = Terminal([*GALILEO, "--port", served.url, "teleop"])
    try:
        terminal.expect(b"q quit")
        terminal.send(b"s")
        terminal.expect(b"backward 30%")
        served.wait_for(lambda state: (state.status.current_speed_x or 0.0) < -0.1)
        terminal.process.send_signal(signal.SIGINT)
        assert terminal.process.wait(WAIT) == 0
        served.wait_for(lambda state: state.status.current_speed_x == 0.0)
    finally:
        terminal.close()


@pytest.mark.skipif(not hasattr(os, "openpty"), reason="needs a POSIX pty")
def test_goto_shows_live_progress_on_a_terminal() -> None:
    terminal = Terminal([*GALILEO, "--port", "sim://?speed=4", "goto", "1"])
    try:
        terminal.expect(b"goto 1 \xc2\xb7")  # the live line: label · elapsed · goal state
        terminal.expect(b"m to go")
        terminal.expect(b"arrived at target 1")
        assert terminal.process.wait(WAIT) == 0
    finally:
        terminal.close()
