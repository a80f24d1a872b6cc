"""``galileo stop``, and ``stop`` / ``cancel`` / ``pause`` from a second terminal.

While ``galileo goto`` owns a serial port (a pty the simulator serves), ``galileo stop``
in another process goes through the goto's control socket; each side is a real process.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import os
import sys
from collections.abc import AsyncIterator, Mapping
from pathlib import Path
from typing import Any

import pytest

import galileo_async as galileo
from galileo_async.cli import ExitCode
from galileo_async.cli.runner import exit_code_for
from galileo_async.errors import StopUnconfirmed
from galileo_async.protocol import Cancel, Command, Goto, Pause, Stop
from galileo_async.robot.control import control_key, socket_path
from galileo_async.robot.control_server import ControlOperation, serve_control
from galileo_async.sim import Simulator
from tests.cli.test_cli import invoke

linux_only = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="pty is Linux-only")

GALILEO = [sys.executable, "-m", "galileo_async"]
#: Bound on one step of a test with real processes (each starts a Python), seconds.
WAIT = 60.0


# --- galileo stop on its own ------------------------------------------------------------------


def test_stop_says_what_was_stopped() -> None:
    result = invoke("stop")
    assert result.exit_code == 0, result.output
    assert result.stdout.strip() == "nothing was moving"
    result = invoke("stop", "--brake", "30", "--json")
    assert result.exit_code == 0, result.output
    assert json.loads(result.stdout) == {
        "port": "sim://?speed=20", "result": "ok", "done": "nothing was moving", "stopped": [],
    }  # fmt: skip


def test_stop_checks_its_arguments() -> None:
    for args in (["--brake", "101"], ["--brake", "-1"], ["--timeout", "0"], ["--timeout", "61"]):
        result = invoke("stop", *args)
        assert result.exit_code == ExitCode.USAGE, (args, result.output)


def test_stop_is_the_command_that_stops_everything() -> None:
    result = invoke("--help", port=None)
    assert " stop " in result.stdout
    assert "Stop everything" in result.stdout
    text = " ".join(invoke("stop", "--help", port=None).stdout.split())
    for other in ("nav stop", "patrol stop", "charge stop"):
        assert other in text


def test_a_stop_the_robot_does_not_confirm_exits_6() -> None:
    unconfirmed = StopUnconfirmed("stop: still moving", None, unconfirmed=("speed",))
    assert exit_code_for(unconfirmed) == ExitCode.TIMEOUT == 6
    assert exit_code_for(StopUnconfirmed) == ExitCode.TIMEOUT


def test_pause_and_cancel_on_the_simulator() -> None:
    result = invoke("pause")
    assert result.exit_code == ExitCode.NOT_READY, result.output
    assert "the goal must be working" in result.stderr
    result = invoke("cancel", "--json")
    assert result.exit_code == 0, result.output
    assert json.loads(result.stdout)["goal_was_running"] is False


# --- a second process ------------------------------------------------------------------------


def environment() -> dict[str, str]:
    env = {key: value for key, value in os.environ.items() if key != "GALILEO_PORT"}
    return env | {"COLUMNS": "200"}


async def start(*args: str) -> asyncio.subprocess.Process:
    return await asyncio.create_subprocess_exec(
        *GALILEO, *args, stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE,
        env=environment(),
    )  # fmt: skip


async def finish(process: asyncio.subprocess.Process) -> tuple[int, str, str]:
    out, err = await asyncio.wait_for(process.communicate(), WAIT)
    assert process.returncode is not None
    return process.returncode, out.decode(), err.decode()


async def galileo_cli(*args: str) -> tuple[int, str, str, int]:
    """Run ``galileo args…`` to its end: exit code, stdout, stderr, pid."""
    process = await start(*args)
    return (*await finish(process), process.pid)


@contextlib.asynccontextmanager
async def driving(pty: str, sim: Simulator) -> AsyncIterator[asyncio.subprocess.Process]:
    """``galileo -p PTY goto 0`` in a process of its own, once its goal was sent."""
    goal_sent = asyncio.Event()
    sim.on_command(lambda command: goal_sent.set() if isinstance(command, Goto) else None)
    process = await start("-p", pty, "goto", "0", "--start-nav", "--timeout", "120")
    try:
        await asyncio.wait_for(goal_sent.wait(), WAIT)
        yield process
    finally:
        if process.returncode is None:
            with contextlib.suppress(ProcessLookupError):
                process.kill()
            await process.wait()


@pytest.fixture
async def slow_sim() -> AsyncIterator[Simulator]:
    """A robot whose 2 m to target 0 take 40 s: the goal outlasts the other processes."""
    async with Simulator(speed=5, max_speed=0.01) as sim:
        yield sim


def commands_of(sim: Simulator) -> list[Command]:
    commands: list[Command] = []
    sim.on_command(commands.append)
    return commands


@linux_only
async def test_stop_in_a_second_terminal_goes_through_the_goto(
    runtime_dir: Path, slow_sim: Simulator
) -> None:
    pty = slow_sim.open_pty()
    commands = commands_of(slow_sim)
    async with driving(pty, slow_sim) as goto:
        code, out, err, stopper = await galileo_cli("-p", pty, "stop")
        assert code == 0, err
        assert f"(through the owning process {goto.pid}: " in out
        assert "goto 0" in out  # the owner's command line
        assert out.startswith("goal 0 cancelled")
        assert commands[-2:] == [Cancel(), Stop(100)]  # the owner wrote them to the robot
        code, out, err = await finish(goto)  # its goto ended by the stop
    assert code == ExitCode.CANCELLED, (out, err)
    assert "GoalCancelled" in err
    assert "stop()" in err  # names what cancelled it
    logged = f"stop (brake 100) asked through the control socket by process {stopper}"
    asked = f"galileo: {pty}: {logged} (uid {os.getuid()}): "
    assert f"{asked}{sys.executable} -m galileo_async -p {pty} stop\n" in err  # its command
    key = control_key(pty)
    assert key is not None
    assert not socket_path(key).exists()  # the goto removed its socket on the way out


@linux_only
async def test_pause_from_a_second_terminal_as_json(runtime_dir: Path, slow_sim: Simulator) -> None:
    pty = slow_sim.open_pty()
    commands = commands_of(slow_sim)
    async with driving(pty, slow_sim) as goto:
        code, out, err, _ = await galileo_cli("-p", pty, "--json", "pause")
        assert code == 0, err
        answer = json.loads(out)
        assert answer["port"] == pty
        assert answer["result"] == "ok"
        assert answer["done"] == "goal paused"
        assert answer["owner"]["pid"] == goto.pid
        assert "goto 0" in answer["owner"]["command"]
        assert Pause() in commands
        code, out, err, _ = await galileo_cli("-p", pty, "cancel")
        assert code == 0, err
        assert f"goal cancelled (through the owning process {goto.pid}: " in out
        code, out, err = await finish(goto)
    assert code == ExitCode.CANCELLED, (out, err)


@linux_only
async def test_a_port_held_without_a_control_socket_is_still_busy(runtime_dir: Path) -> None:
    async with Simulator(speed=20) as sim:
        pty = sim.open_pty()
        async with galileo.connect(pty):  # an application that did not opt in
            code, out, err, _ = await galileo_cli("-p", pty, "cancel")
    assert code == ExitCode.PORT_BUSY, (out, err)
    assert "PortBusy" in err
    assert "no galileo process serves its control socket" in err
    assert "control_socket=True" in err


def answering(fields: Mapping[str, Any] | Exception) -> dict[str, ControlOperation]:
    """Operations that answer ``fields`` or raise the error, whatever is asked."""

    async def operation(request: Mapping[str, Any]) -> dict[str, Any]:
        if isinstance(fields, Exception):
            raise fields
        return dict(fields)

    return dict.fromkeys(("stop", "cancel", "pause"), operation)


@linux_only
async def test_an_owner_that_cannot_confirm_the_stop_makes_it_exit_6(runtime_dir: Path) -> None:
    port = str(runtime_dir / "ttyOWNED")  # only the owner's socket is asked: nothing opens it
    error = StopUnconfirmed("stop: the robot still moved after 5.0 s", None, unconfirmed=("speed",))
    server = await serve_control(port, answering(error))
    assert server is not None
    try:
        code, out, err, _ = await galileo_cli("-p", port, "stop")
        assert code == ExitCode.TIMEOUT, (out, err)
        assert "StopUnconfirmed: stop: the robot still moved after 5.0 s" in err
        assert f"(in process {os.getpid()}, which owns it)" in err
        code, out, err, _ = await galileo_cli("-p", port, "--json", "stop")
        assert code == ExitCode.TIMEOUT
        assert json.loads(out) == {
            "error": "StopUnconfirmed",
            "message": f"stop: the robot still moved after 5.0 s (in process {os.getpid()}, "
            "which owns it)",
            "exit_code": 6,
        }
    finally:
        await server.close()
