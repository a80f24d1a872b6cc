"""``--metrics [HOST:]PORT``: usage errors before anything connects, and served while running."""

from __future__ import annotations

import asyncio
import signal
import socket
import subprocess
import sys
import time
import urllib.request
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest

from galileo_async.cli import ExitCode
from galileo_async.cli.metrics_opt import metrics_address
from galileo_async.metrics import DEFAULT_METRICS_HOST
from tests.cli.test_cli import invoke
from tests.support.metrics_support import WAIT, free_port, prometheus, query
from tests.support.vda5050_support import Broker

FAST = "sim://?speed=20"
#: The long-running commands with --metrics, each with what it needs besides.
COMMANDS = {
    "monitor": ["monitor", "--json"],
    "vda5050": [
        "vda5050",
        "--broker",
        "mqtt://127.0.0.1:1",
        "--manufacturer",
        "m",
        "--serial-number",
        "s",
    ],
    "mission schedule": ["mission", "schedule", "no-such-schedule.yaml"],
    "foxglove": ["foxglove", "--port", "0"],
}


def test_the_address_forms() -> None:
    assert metrics_address(None) is None
    assert metrics_address("9464") == (DEFAULT_METRICS_HOST, 9464)
    assert metrics_address("0.0.0.0:9000") == ("0.0.0.0", 9000)
    assert metrics_address("[::1]:9000") == ("::1", 9000)


@pytest.mark.parametrize("command", COMMANDS)
@pytest.mark.parametrize("bad", ["", "x", "host:", ":9464", "127.0.0.1:0", "1:65536"])
def test_a_bad_address_is_a_usage_error_before_anything_connects(command: str, bad: str) -> None:
    result = invoke(*COMMANDS[command], "--metrics", bad, port="socket://127.0.0.1:1")
    assert result.exit_code == ExitCode.USAGE, result.output
    assert "Invalid value for --metrics" in result.output
    assert "connect" not in result.output.lower()


def test_a_schedule_played_with_sim_serves_none(tmp_path: Path) -> None:
    schedule = tmp_path / "schedule.yaml"
    schedule.write_text("not: a schedule\n")
    result = invoke("mission", "schedule", str(schedule), "--sim", "--metrics", "9464", port=None)
    assert result.exit_code == ExitCode.USAGE, result.output
    assert "--metrics is for a robot's schedule, not --sim" in result.output


def test_fleet_monitor_takes_it_too(tmp_path: Path) -> None:
    fleet = tmp_path / "fleet.toml"
    fleet.write_text('[robots.a]\nport = "socket://127.0.0.1:1"\n')
    result = invoke("--fleet", str(fleet), "fleet", "monitor", "--metrics", "x:y", port=None)
    assert result.exit_code == ExitCode.USAGE, result.output
    assert "Invalid value for --metrics: 'x:y'" in result.output


def test_a_port_in_use_is_an_error_naming_it() -> None:
    with socket.socket() as holder:
        holder.bind(("127.0.0.1", 0))
        holder.listen()
        port = holder.getsockname()[1]
        result = invoke("monitor", "--json", "--duration", "1", "--metrics", str(port), port=FAST)
    assert result.exit_code == ExitCode.ERROR, result.output
    assert f"cannot serve metrics on 127.0.0.1:{port}: Address already in use" in result.output


@contextmanager
def galileo(*args: str) -> Iterator[subprocess.Popen[bytes]]:
    """``galileo args…`` in a subprocess, interrupted (SIGINT) and waited for on every exit."""
    process = subprocess.Popen(
        [sys.executable, "-m", "galileo_async", *args],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        yield process
    finally:
        if process.poll() is None:
            process.send_signal(signal.SIGINT)
            try:
                process.wait(timeout=WAIT)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()


def scrape_until(url: str, needle: str, process: subprocess.Popen[bytes]) -> str:
    """GET ``url`` until its text holds ``needle`` (bounded; fails if the process ended)."""
    deadline = time.monotonic() + WAIT
    text = ""
    while time.monotonic() < deadline:
        assert process.poll() is None, "galileo ended"
        try:
            with urllib.request.urlopen(url, timeout=5) as answer:
                text = answer.read().decode()
        except OSError:
            text = ""
        if needle in text:
            return text
        time.sleep(0.2)
    raise AssertionError(f"{needle!r} not served within {WAIT} s: {text[-2000:]}")


def test_monitor_serves_its_robot_and_closes_the_port_on_exit() -> None:
    port = free_port()
    url = f"http://127.0.0.1:{port}/metrics"
    with galileo("--port", FAST, "monitor", "--json", "--metrics", str(port)) as process:
        text = scrape_until(
            url, 'galileo_link_state{galileo_link_state="up",robot="sim://', process
        )
        assert f'galileo_frames_received_total{{robot="{FAST}"}}' in text
        process.send_signal(signal.SIGINT)
        assert process.wait(timeout=WAIT) == ExitCode.OK
    with socket.socket() as probe:
        assert probe.connect_ex(("127.0.0.1", port)) != 0


def test_foxglove_serves_the_metrics_of_every_robot_of_its_fleet(tmp_path: Path) -> None:
    fleet = tmp_path / "fleet.toml"
    fleet.write_text(f'[robots.alpha]\nport = "{FAST}"\n[robots.beta]\nport = "{FAST}"\n')
    port = free_port()
    url = f"http://127.0.0.1:{port}/metrics"
    args = ("--fleet", str(fleet), "foxglove", "--port", "0", "--metrics", str(port))
    with galileo(*args) as process:
        text = scrape_until(url, 'galileo_frames_received_total{robot="beta"}', process)
        assert 'galileo_frames_received_total{robot="alpha"}' in text
        process.send_signal(signal.SIGINT)
        assert process.wait(timeout=WAIT) == ExitCode.OK
    with socket.socket() as probe:
        assert probe.connect_ex(("127.0.0.1", port)) != 0


async def test_a_real_prometheus_scrapes_galileo_fleet_monitor(tmp_path: Path) -> None:
    fleet = tmp_path / "fleet.toml"
    fleet.write_text("".join(f'[robots.r{i}]\nport = "{FAST}"\n' for i in range(3)))
    port = free_port()
    with (
        galileo("--fleet", str(fleet), "fleet", "monitor", "--metrics", f"127.0.0.1:{port}"),
        prometheus([f"127.0.0.1:{port}"]) as base,
    ):
        series = await query(base, "galileo_frames_received_total > 0", until_series=3)
        assert {s["metric"]["robot"] for s in series} == {"r0", "r1", "r2"}


async def test_vda5050_fleet_serves_each_connected_robot(tmp_path: Path) -> None:
    fleet = tmp_path / "fleet.toml"
    fleet.write_text("".join(f'[robots.v{i}]\nport = "{FAST}"\n' for i in range(2)))
    port = free_port()
    url = f"http://127.0.0.1:{port}/metrics"
    async with Broker.running(tmp_path) as broker:
        args = ["vda5050", "--fleet", str(fleet), "--broker", broker.url, "--manufacturer", "m"]
        with galileo(*args, "--metrics", str(port)) as process:
            for name in ("v0", "v1"):
                needle = f'galileo_frames_received_total{{robot="{name}"}}'
                await asyncio.to_thread(scrape_until, url, needle, process)
            process.send_signal(signal.SIGINT)
            assert await asyncio.to_thread(process.wait, WAIT) == ExitCode.OK
