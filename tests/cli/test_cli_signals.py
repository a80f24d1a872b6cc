"""SIGTERM and SIGHUP end a command the way Ctrl-C does: cancel, one stop, a line, 128+signal."""

from __future__ import annotations

import asyncio
import contextlib
import json
import os
import signal
import subprocess
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
import typer

from galileo_async.cli.runner import Settings, run
from galileo_async.cli.signals import STOP_SIGNALS, stop_requested, stop_signal
from galileo_async.protocol import (
    Cancel,
    Command,
    Forward,
    Goto,
    RotateTo,
    SetPatrolDwell,
    StartPatrol,
    Stop,
)
from galileo_async.sim import SimState
from galileo_async.sim.replay import MAGIC
from tests.cli.test_cli_served import GALILEO, ServedSim, Terminal, ok, working
from tests.cli.test_cli_served import _read_until as read_until

#: Bound on every wait for an event of these tests (generous: a loaded machine), seconds.
WAIT = 60.0

#: (signal, exit code) of every signal that ends a command the way Ctrl-C does.
CODES = [(signal.SIGTERM, 143), (signal.SIGHUP, 129), (signal.SIGINT, 130)]
IDS = ["SIGTERM", "SIGHUP", "SIGINT"]


class Received:
    """Every command the served robot takes from now on, in order (kept by its own loop)."""

    def __init__(self, served: ServedSim) -> None:
        self.commands: list[Command] = []
        self._lock = threading.Lock()

        async def attach() -> None:
            assert served.simulator is not None
            served.simulator.on_command(self._record)

        served.run_soon(attach()).result(WAIT)

    def _record(self, command: Command) -> None:
        with self._lock:
            self.commands.append(command)

    def kinds(self) -> list[type[Command]]:
        with self._lock:
            return [type(command) for command in self.commands]

    def after(self, kind: type[Command]) -> list[type[Command]]:
        """The kinds of the commands taken after the first ``kind``."""
        kinds = self.kinds()
        assert kind in kinds, kinds
        return kinds[kinds.index(kind) + 1 :]


def moving(state: SimState) -> bool:
    status = state.status
    return abs(status.current_speed_x or 0.0) > 0.1 or abs(status.current_speed_theta or 0.0) > 0.1


def stopped(state: SimState) -> bool:
    """No goal working or paused, both speeds zero (the robot's own, not the commanded ones)."""
    status = state.status
    return not status.goal_active and status.current_speed_x == 0 == status.current_speed_theta


def start(*args: str) -> subprocess.Popen[str]:
    """``galileo ARGS`` in a child process; stdout and stderr piped (neither a terminal)."""
    return subprocess.Popen(
        [*GALILEO, *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )


def finish(process: subprocess.Popen[str], sig: signal.Signals) -> tuple[int, str, str]:
    """Send ``sig``, then (exit code, stdout, stderr) once the process ended."""
    try:
        process.send_signal(sig)
        out, err = process.communicate(timeout=WAIT)
    finally:
        process.kill()
        process.communicate()
    return process.returncode, out, err


@contextlib.contextmanager
def served_at(speed: float, **config: object) -> Iterator[ServedSim]:
    """A simulated robot over TCP at ``speed`` with ``config``, navigation open."""
    served = ServedSim(speed=speed, **config)
    try:
        ok(served.url, "nav", "start")
        yield served
    finally:
        served.close()


@pytest.fixture
def robot() -> Iterator[ServedSim]:
    """A simulated robot in real time: a goal takes seconds."""
    with served_at(1.0) as served:
        yield served


# --- goals -----------------------------------------------------------------------------------


@pytest.mark.parametrize(("sig", "code"), CODES, ids=IDS)
def test_goto_on_a_signal_cancels_stops_says_so_and_exits_128_plus_it(
    robot: ServedSim, sig: signal.Signals, code: int
) -> None:
    received = Received(robot)
    goto = start("--port", robot.url, "goto", "4")
    robot.wait_for(lambda state: working(state) and moving(state), WAIT)
    returncode, out, err = finish(goto, sig)
    assert returncode == code, err
    assert out == ""
    last = err.splitlines()[-1]
    assert last.startswith(f"interrupted by {sig.name}: goal 4 cancelled (i 2 sent), stop sent"), (
        err
    )
    assert "; robot at (" in last, err
    after = received.after(Goto)
    assert Cancel in after, after
    assert Stop in after[after.index(Cancel) :], after
    robot.wait_for(stopped, WAIT)


def test_goto_with_json_on_sigterm_prints_the_signal_and_the_stop(robot: ServedSim) -> None:
    goto = start("--json", "--port", robot.url, "goto", "4")
    robot.wait_for(lambda state: working(state) and moving(state), WAIT)
    returncode, out, err = finish(goto, signal.SIGTERM)
    assert returncode == 143, err
    data = json.loads(out)
    assert data["result"] == "interrupted"
    assert data["signal"] == "SIGTERM"
    assert data["target_id"] == 4
    assert data["cancel_sent"] is True
    assert data["stop_sent"] is True
    assert set(data["pose"]) == {"x", "y", "degrees"}
    assert "interrupted" not in err  # --json: the result is the JSON line


def test_goto_point_on_sigterm_cancels_and_stops(robot: ServedSim) -> None:
    received = Received(robot)
    goto = start("--port", robot.url, "--map-targets", "6", "goto-point", "4.5", "-3.5")
    robot.wait_for(lambda state: working(state) and moving(state), WAIT)
    returncode, _, err = finish(goto, signal.SIGTERM)
    assert returncode == 143, err
    last = err.splitlines()[-1]
    assert last.startswith("interrupted by SIGTERM: the goal cancelled (i 2 sent), stop sent"), err
    assert "; robot at (" in last, err
    after = received.after(Goto)
    assert Cancel in after, after
    assert Stop in after[after.index(Cancel) :], after
    robot.wait_for(stopped, WAIT)


def test_rotate_on_sighup_sends_a_stop() -> None:
    # Document firmware turns on 'a'; a quarter of real time: a half turn takes ~8 s.
    with served_at(0.25, firmware="document") as served:
        received = Received(served)
        rotate = start("--port", served.url, "rotate", "180", "--timeout", str(WAIT))
        served.wait_for(moving, WAIT)
        returncode, _, err = finish(rotate, signal.SIGHUP)
        assert returncode == 129, err
        last = err.splitlines()[-1]
        assert last.startswith("interrupted by SIGHUP: stop sent"), err
        assert "; robot at (" in last, err
        assert Stop in received.after(RotateTo)


def test_patrol_start_on_sigterm_sends_a_stop() -> None:
    # A robot busy for long after nav start: patrol start waits, showing its progress.
    with served_at(1.0, busy_on_start=600.0) as served:
        received = Received(served)
        patrol = start("--port", served.url, "patrol", "start")
        assert patrol.stderr is not None
        read_until(patrol.stderr, "patrol start ·")
        returncode, _, err = finish(patrol, signal.SIGTERM)
        assert returncode == 143, err
        last = err.splitlines()[-1]
        assert last.startswith("interrupted by SIGTERM: stop sent"), err
        assert "; robot at (" in last, err
        assert Stop in received.kinds()
        assert StartPatrol not in received.kinds()  # the robot stayed busy: nothing went out
        assert SetPatrolDwell not in received.kinds()


def test_demo_on_sigterm_stops_its_robot_and_exits_143() -> None:
    demo = start("demo", "--speed", "1")
    assert demo.stderr is not None
    seen = read_until(demo.stderr, "go to target 0")
    returncode, _, err = finish(demo, signal.SIGTERM)
    assert returncode == 143, seen + err
    assert (seen + err).splitlines()[-1].startswith("interrupted by SIGTERM: stop sent"), err


# --- commands that end normally on Ctrl-C ----------------------------------------------------


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGHUP], ids=["SIGTERM", "SIGHUP"])
def test_sim_ends_on_a_signal_as_on_ctrl_c(sig: signal.Signals) -> None:
    server = start("sim", "--tcp", "127.0.0.1:0")
    assert server.stdout is not None
    read_until(server.stdout, "socket://127.0.0.1:")
    returncode, _, err = finish(server, sig)
    assert returncode == 0, err
    assert "Traceback" not in err


def test_record_on_sigterm_keeps_what_it_got_and_exits_0(tmp_path: Path) -> None:
    capture = tmp_path / "capture.glc"
    recorder = start("--port", "sim://", "record", str(capture))
    deadline = time.monotonic() + WAIT
    # The first chunk is written: the recording runs (the file has more than its magic).
    while not capture.exists() or capture.stat().st_size <= len(MAGIC):
        assert time.monotonic() < deadline, "nothing recorded"
        assert recorder.poll() is None, recorder.communicate()
        time.sleep(0.01)
    returncode, out, err = finish(recorder, signal.SIGTERM)
    assert returncode == 0, err
    assert out.startswith("recorded "), out


# --- teleop ------------------------------------------------------------------------------------


@pytest.mark.skipif(not hasattr(os, "openpty"), reason="needs a POSIX pty")
@pytest.mark.parametrize(("sig", "code"), CODES[:2], ids=IDS[:2])
def test_teleop_on_a_signal_stops_and_exits_128_plus_it(
    robot: ServedSim, sig: signal.Signals, code: int
) -> None:
    received = Received(robot)
    terminal = Terminal([*GALILEO, "--port", robot.url, "teleop"])
    try:
        terminal.expect(b"q quit")
        terminal.send(b"w")
        terminal.expect(b"forward 30%")
        robot.wait_for(moving, WAIT)
        terminal.process.send_signal(sig)
        terminal.expect(f"interrupted by {sig.name}: stop sent".encode(), WAIT)
        assert terminal.process.wait(WAIT) == code
        robot.wait_for(stopped, WAIT)
        assert Stop in received.after(Forward)
    finally:
        terminal.close()


# --- the runner ----------------------------------------------------------------------------------


def _run_until_signalled(sig: signal.Signals, *, again: bool = False) -> int:
    """run() a main that waits forever and sends itself ``sig`` (twice with ``again``)."""
    settings = Settings()

    async def main() -> int:
        os.kill(os.getpid(), sig)
        if again:
            await asyncio.sleep(0)  # the first one is handled: the main task is cancelled
            os.kill(os.getpid(), sig)
        await asyncio.Event().wait()
        return 0

    with pytest.raises(typer.Exit) as exited:
        run(settings, main)
    return exited.value.exit_code


@pytest.mark.parametrize(("sig", "code"), CODES, ids=IDS)
def test_run_ends_a_command_on_a_stop_signal_with_128_plus_it(
    sig: signal.Signals, code: int
) -> None:
    before = {number: signal.getsignal(number) for number in STOP_SIGNALS}
    assert _run_until_signalled(sig) == code
    assert {number: signal.getsignal(number) for number in STOP_SIGNALS} == before


def test_a_second_signal_does_not_cut_the_way_out_short(capsys: pytest.CaptureFixture[str]) -> None:
    settings = Settings()
    finished = []

    async def main() -> int:
        os.kill(os.getpid(), signal.SIGTERM)
        try:
            await asyncio.Event().wait()
        finally:
            os.kill(os.getpid(), signal.SIGTERM)  # while it cleans up
            await asyncio.sleep(0.01)
            finished.append(True)
        return 0

    with pytest.raises(typer.Exit) as exited:
        run(settings, main)
    assert exited.value.exit_code == 143
    assert finished == [True]
    assert "SIGTERM again" in capsys.readouterr().err


def test_a_stop_request_block_takes_the_signal_and_the_command_ends_normally() -> None:
    settings = Settings()
    names = []

    async def main() -> int:
        with stop_requested() as stop:
            os.kill(os.getpid(), signal.SIGHUP)
            await stop.wait()
        received = stop_signal()
        assert received is not None
        names.append(received.name)
        return 0

    with pytest.raises(typer.Exit) as exited:
        run(settings, main)
    assert exited.value.exit_code == 0
    assert names == ["SIGHUP"]
