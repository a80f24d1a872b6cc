"""The CLI over ``udp://`` (``galileo sim --udp``): frames without speed show it as unknown."""

from __future__ import annotations

import os
import subprocess
from collections.abc import Iterator

import pytest

from tests.cli.test_cli_served import GALILEO
from tests.cli.test_cli_sim_urls import LINE_WAIT, Sim, start_sim


@pytest.fixture(scope="module")
def udp_url() -> Iterator[str]:
    """The udp:// URL of a ``galileo sim --udp 0`` (it serves HTTP too)."""
    sim: Sim = start_sim("--udp", "0", faces=1)
    try:
        (url,) = [url for url in sim.urls if url.startswith("udp://")]
        yield url
    finally:
        sim.close()


def galileo(url: str, *args: str) -> subprocess.CompletedProcess[str]:
    env = {key: value for key, value in os.environ.items() if key != "GALILEO_PORT"}
    return subprocess.run(
        [*GALILEO, "--port", url, *args],
        capture_output=True, text=True, timeout=LINE_WAIT * 2, env=env, check=False,
    )  # fmt: skip


def test_goto_progress_over_udp_shows_the_speed_as_unknown(udp_url: str) -> None:
    # stderr is a pipe: a plain progress line on each change of state, at least at the accept.
    done = galileo(udp_url, "goto", "1", "--start-nav")
    assert done.returncode == 0, done.stderr
    progress = [line for line in done.stderr.splitlines() if line.startswith("goto 1 · ")]
    assert progress, done.stderr
    for line in progress:
        assert line.endswith(" · speed n/a"), line
    assert "m/s" not in done.stderr


def test_status_watch_over_udp_shows_the_speed_as_unknown(udp_url: str) -> None:
    done = galileo(udp_url, "status", "--watch", "--count", "2", "--interval", "0.05")
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    assert len(lines) == 2
    for line in lines:
        assert line.endswith(" · speed n/a"), line
