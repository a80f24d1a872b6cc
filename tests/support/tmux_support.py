"""A tmux server of a test's own, its screen and keys: for the tests that look at a terminal."""

from __future__ import annotations

import os
import shutil
import subprocess
import uuid
from collections.abc import Callable, Iterator

import anyio

from tests.support.peers import missing_peer

__all__ = ["keys", "screen", "tmux_server", "until"]

#: Bound, in real seconds, of each wait on the screen.
SCREEN_WAIT = 30.0


def tmux_server(columns: int, rows: int) -> Iterator[list[str]]:
    """The tmux command of a server of the caller's own, one pane of this size; killed after."""
    if shutil.which("tmux") is None:
        missing_peer("tmux")
    # A server name of each test's own: a killed server's socket may linger a moment.
    command = ["tmux", "-L", f"galileo-test-{os.getpid()}-{uuid.uuid4().hex[:8]}"]
    subprocess.run([*command, "new-session", "-d", "-s", "main", "-x", str(columns),
                    "-y", str(rows)], check=True)  # fmt: skip
    try:
        yield command
    finally:
        subprocess.run([*command, "kill-server"], check=False)


async def screen(tmux: list[str], *, escapes: bool = False) -> str:
    """The pane's text now (with its SGR escapes when ``escapes``)."""
    flags = ["-e"] if escapes else []
    done = await anyio.run_process([*tmux, "capture-pane", "-p", *flags, "-t", "main"])
    return done.stdout.decode()


async def until(tmux: list[str], holds: Callable[[str], bool], *, escapes: bool = False) -> str:
    """The screen once ``holds`` is true of it (a screen has no event: polled)."""
    with anyio.fail_after(SCREEN_WAIT):
        while not holds(shown := await screen(tmux, escapes=escapes)):  # noqa: ASYNC110
            await anyio.sleep(0.1)
    return shown


async def keys(tmux: list[str], *typed: str) -> None:
    """Type ``typed`` into the pane (tmux send-keys names: "Enter", "C-c", …)."""
    await anyio.run_process([*tmux, "send-keys", "-t", "main", *typed])
