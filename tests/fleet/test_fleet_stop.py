"""Fleet.stop() and ``galileo fleet stop``: every robot at once, a line per robot, one exit code."""

from __future__ import annotations

import asyncio
import json
import os
import sys
from pathlib import Path

import pytest

import galileo_async as galileo
from galileo_async import StopReport, connect_fleet
from galileo_async.cli import ExitCode
from galileo_async.errors import InvalidArgument, NotReady
from galileo_async.protocol import Stop
from galileo_async.sim import Simulator
from galileo_async.testing import simulated_fleet
from tests.cli.test_cli_fleet import invoke
from tests.support.ports import refused_port

SIM = "sim://?speed=50"
GALILEO = [sys.executable, "-m", "galileo_async"]
WAIT = 60.0


async def test_fleet_stop_stops_every_robot_at_once() -> None:
    async with simulated_fleet(3) as (fleet, devices):
        results = await fleet.stop(40)
        assert list(results) == ["robot1", "robot2", "robot3"]
        for name, result in results.items():
            assert result.ok, result.error
            assert isinstance(result.value, StopReport)
            assert devices[name].received(Stop) == [Stop(40)]


async def test_fleet_stop_checks_its_arguments_before_sending() -> None:
    async with simulated_fleet(2) as (fleet, devices):
        with pytest.raises(InvalidArgument, match="brake"):
            await fleet.stop(101)
        with pytest.raises(InvalidArgument, match="timeout"):
            await fleet.stop(timeout=-1)
        assert all(device.commands == [] for device in devices.values())


async def test_a_robot_not_connected_gets_its_error() -> None:
    with refused_port() as port:
        ports = {"a": SIM, "down": f"socket://127.0.0.1:{port}"}
        async with connect_fleet(ports, first_status_timeout=5) as fleet:
            results = await fleet.stop()
    assert results["a"].ok
    error = results["down"].error
    assert isinstance(error, NotReady)
    assert "robot 'down' is not connected" in str(error)
    assert "cannot connect" in str(error)  # why it is not


FLEET = """
[defaults]
first_status_timeout = 5

[robots.alpha]
port = "sim://?speed=20"

[robots.beta]
port = "sim://?speed=20"
"""


def fleet_file(tmp_path: Path, extra: str = "") -> str:
    path = tmp_path / "fleet.toml"
    path.write_text(FLEET + extra)
    return str(path)


def test_fleet_stop_prints_a_line_per_robot(tmp_path: Path) -> None:
    result = invoke("--fleet", fleet_file(tmp_path), "fleet", "stop")
    assert result.exit_code == 0, result.output
    assert result.stdout.splitlines() == ["alpha: nothing was moving", "beta: nothing was moving"]


def test_fleet_stop_exits_7_when_a_robot_cannot_be_reached(tmp_path: Path) -> None:
    with refused_port() as port:
        down = f'\n[robots.down]\nport = "socket://127.0.0.1:{port}"\n'
        path = fleet_file(tmp_path, down)
        result = invoke("--fleet", path, "fleet", "stop")
        assert result.exit_code == ExitCode.CONNECTION, result.output
        lines = result.stdout.splitlines()
        assert lines[:2] == ["alpha: nothing was moving", "beta: nothing was moving"]
        assert lines[2].startswith("down: not reached: GalileoConnectionError: cannot connect")
        result = invoke("--fleet", path, "fleet", "stop", "--json", "--brake", "50")
    assert result.exit_code == ExitCode.CONNECTION
    rows = [json.loads(line) for line in result.stdout.splitlines()]
    assert [(row["name"], row["result"]) for row in rows] == [
        ("alpha", "ok"), ("beta", "ok"), ("down", "error"),
    ]  # fmt: skip
    assert rows[0]["stopped"] == []
    assert rows[0]["port"] == "sim://?speed=20"
    assert rows[2]["error"] == "GalileoConnectionError"
    assert rows[2]["exit_code"] == ExitCode.CONNECTION


def test_fleet_stop_needs_a_fleet_file() -> None:
    result = invoke("fleet", "stop")
    assert result.exit_code == ExitCode.USAGE
    assert "--fleet" in result.stderr


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="pty is Linux-only")
async def test_a_robot_another_process_drives_is_stopped_through_it(
    runtime_dir: Path, tmp_path: Path
) -> None:
    async with Simulator(speed=20) as sim:
        pty = sim.open_pty()
        stops: list[object] = []
        sim.on_command(lambda command: stops.append(command) if command == Stop(100) else None)
        path = fleet_file(tmp_path, f'\n[robots.serial]\nport = "{pty}"\n')
        env = {k: v for k, v in os.environ.items() if k != "GALILEO_FLEET"}
        async with galileo.connect(pty, control_socket=True):  # the port's owner: this process
            process = await asyncio.create_subprocess_exec(
                *GALILEO, "--fleet", path, "fleet", "stop", env=env,
                stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE,
            )  # fmt: skip
            out, err = await asyncio.wait_for(process.communicate(), WAIT)
    assert process.returncode == 0, err.decode()
    lines = out.decode().splitlines()
    assert lines[:2] == ["alpha: nothing was moving", "beta: nothing was moving"]
    assert lines[2].startswith(
        f"serial: nothing was moving (through the owning process {os.getpid()}: "
    )
    assert stops == [Stop(100)]
