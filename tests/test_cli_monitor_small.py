"""``galileo monitor`` in an 80x24 terminal (tmux): the map shows, keys q, m and ? work."""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
import uuid
from collections.abc import Callable, Iterator

import anyio
import pytest
from peers import missing_peer
from test_cli_served import GALILEO, WAIT

import galileo_async as galileo
from galileo_async.errors import GoalCancelled
from galileo_async.sim import Simulator

COLUMNS, ROWS = 80, 24
SIM_URL = "sim://?speed=4&visual_init_time=0.5"


@pytest.fixture
def tmux() -> Iterator[list[str]]:
    """The tmux command of a server of this test's own, an 80x24 pane, killed afterwards."""
    if shutil.which("tmux") is None:
        missing_peer("tmux")
    command = ["tmux", "-L", f"galileo-small-{os.getpid()}-{uuid.uuid4().hex[:8]}"]
    subprocess.run([*command, "new-session", "-d", "-s", "main", "-x", str(COLUMNS),
                    "-y", str(ROWS)], check=True)  # fmt: skip
    try:
        yield command
    finally:
        subprocess.run([*command, "kill-server"], check=False)


async def _screen(tmux: list[str], *, escapes: bool = False) -> str:
    flags = ["-e"] if escapes else []
    done = await anyio.run_process([*tmux, "capture-pane", "-p", *flags, "-t", "main"])
    return done.stdout.decode()


async def _until(tmux: list[str], holds: Callable[[str], bool], *, escapes: bool = False) -> str:
    """The screen once ``holds`` is true of it (a screen has no event: polled)."""
    with anyio.fail_after(WAIT):
        while not holds(screen := await _screen(tmux, escapes=escapes)):  # noqa: ASYNC110
            await anyio.sleep(0.1)
    return screen


def _coloured(screen: str, word: str, colour: str) -> bool:
    """Whether ``word`` shows on the captured ``screen`` in SGR colour ``colour`` (32 green)."""
    for match in re.finditer(r"((?:\x1b\[[0-9;]*m)+)" + re.escape(word), screen):
        if colour in re.findall(r"[0-9]+", match.group(1)):
            return True
    return False


async def _keys(tmux: list[str], *keys: str) -> None:
    await anyio.run_process([*tmux, "send-keys", "-t", "main", *keys])


async def _start_monitor(tmux: list[str], url: str) -> None:
    monitor = f"{sys.executable} -m galileo_async -p {url} monitor; echo monitor-exited-$?"
    await _keys(tmux, "clear; " + monitor, "Enter")


async def test_monitor_at_80x24_shows_the_map_and_answers_its_keys(tmux: list[str]) -> None:
    await _start_monitor(tmux, f"'{SIM_URL}'")
    screen = await _until(tmux, lambda s: "─ map ─" in s and "◆" in s)
    assert "q quit" in screen
    lines = screen.splitlines()
    assert lines[0].startswith("galileo monitor")  # nothing scrolled off the top
    await _keys(tmux, "xyz")  # not echoed over the screen
    await _keys(tmux, "m")
    screen = await _until(tmux, lambda s: "─ map ─" not in s)
    assert "xyz" not in screen
    await _keys(tmux, "m")
    await _until(tmux, lambda s: "─ map ─" in s)
    await _keys(tmux, "?")
    await _until(tmux, lambda s: "show or hide the map" in s)
    await _keys(tmux, "?")
    await _until(tmux, lambda s: "─ map ─" in s)
    await _keys(tmux, "q")
    await _until(tmux, lambda s: "monitor-exited-0" in s)


async def _goto_cancelled(robot: galileo.Robot) -> None:
    with pytest.raises(GoalCancelled):
        await robot.goto(1)


async def test_monitor_colours_follow_the_states(tmux: list[str]) -> None:
    async with Simulator.from_url(SIM_URL) as simulator:
        server = await simulator.serve_tcp()
        try:
            url = f"socket://127.0.0.1:{server.sockets[0].getsockname()[1]}"
            await _start_monitor(tmux, url)
            await _until(tmux, lambda s: "nav closed" in s)
            async with galileo.connect(url, map_targets=6) as robot:
                await robot.start_navigation(timeout=WAIT)
                await _until(tmux, lambda s: _coloured(s, "open", "32"), escapes=True)
                async with anyio.create_task_group() as group:
                    group.start_soon(_goto_cancelled, robot)
                    await _until(tmux, lambda s: _coloured(s, "working", "36"), escapes=True)
                    await robot.cancel()
            await _keys(tmux, "q")
            await _until(tmux, lambda s: "monitor-exited-0" in s)
        finally:
            server.close()


def test_monitor_json_prints_status_lines() -> None:
    env = {key: value for key, value in os.environ.items() if key != "GALILEO_PORT"}
    result = subprocess.run(
        [*GALILEO, "--port", "sim://?speed=20", "monitor", "--json", "--duration", "1.5"],
        capture_output=True, text=True, timeout=WAIT, env=env, check=False,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    lines = [json.loads(line) for line in result.stdout.splitlines()]
    assert any("status" in line for line in lines)
