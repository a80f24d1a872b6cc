"""``galileo foxglove``: a fleet file behind one server; Ctrl-C and SIGTERM end it with 0."""

from __future__ import annotations

import asyncio
import re
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from tests.support.foxglove_support import WAIT, connected

GALILEO = [sys.executable, "-m", "galileo_async"]


async def started(*args: str) -> tuple[asyncio.subprocess.Process, str]:
    """The command running, and the URL its first stderr line names."""
    process = await asyncio.create_subprocess_exec(
        *GALILEO, *args, stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE
    )
    assert process.stderr is not None
    seen = b""
    try:
        async with asyncio.timeout(WAIT):
            while (found := re.search(rb"ws://[\d.]+:\d+", seen)) is None:
                line = await process.stderr.readline()
                assert line, seen.decode()
                seen += line
    except BaseException:
        process.kill()
        await process.wait()
        raise
    return process, found[0].decode()


async def ended(process: asyncio.subprocess.Process, how: signal.Signals) -> int:
    process.send_signal(how)
    try:
        await asyncio.wait_for(process.communicate(), WAIT)
    finally:
        if process.returncode is None:
            process.kill()
            await process.wait()
    assert process.returncode is not None
    return process.returncode


@pytest.mark.parametrize("how", [signal.SIGINT, signal.SIGTERM])
async def test_a_fleet_file_is_served_as_one_prefix_per_robot(
    tmp_path: Path, how: signal.Signals
) -> None:
    fleet = tmp_path / "fleet.toml"
    fleet.write_text(
        '[robots.alpha]\nport = "sim://?speed=5"\n[robots.beta]\nport = "sim://?speed=5"\n'
    )
    process, url = await started("foxglove", "--fleet", str(fleet), "--port", "0")
    try:
        async with connected(url) as client:
            await client.until(lambda: len(client.services) == 14)
            assert {topic.split("/")[1] for topic in client.channels} == {"alpha", "beta"}
            await client.subscribe("/beta/link")
            assert b'"state": "up"' in await client.next_message("/beta/link")
            # The simulated robots of sim:// know their map: the scene shows its targets.
            await client.subscribe("/alpha/scene")
            assert b"alpha/target/0" in await client.next_message("/alpha/scene")
    finally:
        code = await ended(process, how)
    assert code == 0


async def test_one_robot_is_served_under_its_name() -> None:
    process, url = await started("-p", "sim://", "foxglove", "--port", "0", "--name", "solo")
    try:
        async with connected(url) as client:
            await client.until(lambda: "/solo/goto" in client.services)
            await client.subscribe("/solo/status")
            assert b'"nav_status":1' in await client.next_message("/solo/status")
    finally:
        code = await ended(process, signal.SIGINT)
    assert code == 0


def test_without_the_sdk_the_command_says_how_to_get_it() -> None:
    code = (
        "import runpy, sys\nsys.modules['foxglove'] = None\n"
        "sys.argv = ['galileo', '-p', 'sim://', 'foxglove']\n"
        "runpy.run_module('galileo_async', run_name='__main__')\n"
    )
    result = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=WAIT, check=False
    )
    assert result.returncode == 1
    assert result.stderr.count("\n") == 1, result.stderr  # one line, no traceback
    assert "(foxglove is not installed): pip install 'galileo-async[foxglove]'" in result.stderr


def test_fleet_and_port_together_are_a_usage_error(tmp_path: Path) -> None:
    fleet = tmp_path / "fleet.toml"
    fleet.write_text('[robots.alpha]\nport = "sim://"\n')
    result = subprocess.run(
        [*GALILEO, "-p", "sim://", "foxglove", "--fleet", str(fleet)],
        capture_output=True, text=True, timeout=WAIT, check=False,
    )  # fmt: skip
    assert result.returncode == 2
    assert "drop --port" in result.stderr
