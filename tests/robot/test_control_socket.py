"""The control socket: the process that owns a port takes stop, cancel and pause from others.

The owner is a Robot connected with ``control_socket=True`` to a pty the simulator serves
(as a USB adapter gives /dev/ttyUSB0); the asker is ``ask_owner``, as ``galileo stop``
uses it. Every test gets a directory of its own through $XDG_RUNTIME_DIR.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import os
import re
import shlex
import socket
import stat
import sys
from collections.abc import AsyncIterator, Callable, Mapping
from pathlib import Path
from typing import Any

import pytest

import galileo_async as galileo
from galileo_async.models import TargetStatus
from galileo_async.protocol import Cancel, Command, Pause, Stop
from galileo_async.robot import control, control_server
from galileo_async.robot.control import (
    DIRECTORY_NAME,
    ControlUnavailable,
    NoOwner,
    Peer,
    ask_owner,
    control_key,
    socket_path,
)
from galileo_async.robot.control_server import ControlServer, serve_control
from galileo_async.sim import Simulator
from tests.support.cancel_ways import WAYS, stop_waiting

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="pty is Linux-only")

WAIT = 15.0
SERVER_LOG = "galileo_async.robot.control_server"


@pytest.fixture
async def sim() -> AsyncIterator[Simulator]:
    async with Simulator(speed=20) as simulator:
        yield simulator


def received(sim: Simulator) -> list[Command]:
    commands: list[Command] = []
    sim.on_command(commands.append)
    return commands


def path_of(url: str) -> Path:
    key = control_key(url)
    assert key is not None
    return socket_path(key)


class Operations:
    """Stand-in operations for a server without a Robot: they record and can be held."""

    def __init__(self) -> None:
        self.calls: list[tuple[str, Mapping[str, Any]]] = []
        self.started = asyncio.Event()
        self.release = asyncio.Event()
        self.finished = asyncio.Event()
        self.hold = False

    def table(self) -> dict[str, control_server.ControlOperation]:
        def operation(op: str) -> control_server.ControlOperation:
            async def run(request: Mapping[str, Any]) -> dict[str, Any]:
                self.calls.append((op, request))
                self.started.set()
                if self.hold:
                    await self.release.wait()
                self.finished.set()
                return {"done": f"{op} done"}

            return run

        return {op: operation(op) for op in ("stop", "cancel", "pause")}


@contextlib.asynccontextmanager
async def serving(
    url: str, operations: Operations, credentials: Any = None
) -> AsyncIterator[ControlServer]:
    extra = {} if credentials is None else {"credentials": credentials}
    server = await serve_control(url, operations.table(), **extra)
    assert server is not None
    try:
        yield server
    finally:
        await server.close()


def fake_port(runtime_dir: Path) -> str:
    """A serial device path for a server without a port (nothing opens it)."""
    return str(runtime_dir / "ttyFAKE0")


# --- through a Robot ------------------------------------------------------------------------


async def test_stop_cancel_and_pause_go_through_the_owner(
    runtime_dir: Path, sim: Simulator, caplog: pytest.LogCaptureFixture
) -> None:
    pty = sim.open_pty()
    commands = received(sim)
    caplog.set_level(logging.WARNING, SERVER_LOG)
    async with galileo.connect(pty, control_socket=True):
        stopped = await ask_owner(pty, "stop", brake=40)
        assert stopped.ok, stopped.fields
        assert stopped.pid == os.getpid()
        assert stopped.fields["done"] == str(galileo.StopReport())  # nothing was moving
        assert stopped.fields["stopped"] == []
        cancelled = await ask_owner(pty, "cancel")
        assert cancelled.fields["done"] == "no goal was running"
        assert cancelled.fields["goal_was_running"] is False
        paused = await ask_owner(pty, "pause")  # no working goal: the Robot's own refusal
        assert not paused.ok
        assert paused.error == "NotReady"
        assert "must be working" in paused.message
    assert Stop(40) in commands
    assert Cancel() in commands
    assert Pause() not in commands
    asked = [r.getMessage() for r in caplog.records if r.name == SERVER_LOG]
    assert (
        f"{pty}: stop (brake 40) asked through the control socket by process {os.getpid()}"
        in (asked[0])
    )
    assert f"(uid {os.getuid()})" in asked[0]
    assert "pytest" in asked[0] or "python" in asked[0]  # its command line, from /proc
    assert [line.split(" asked")[0] for line in asked[:3]] == [
        f"{pty}: stop (brake 40)", f"{pty}: cancel", f"{pty}: pause",
    ]  # fmt: skip


async def test_the_directory_and_the_socket_are_the_users_only(
    runtime_dir: Path, sim: Simulator
) -> None:
    pty = sim.open_pty()
    async with galileo.connect(pty, control_socket=True):
        path = path_of(pty)
        assert path.parent == runtime_dir / DIRECTORY_NAME
        directory, sock = os.lstat(path.parent), os.lstat(path)
        assert stat.S_ISDIR(directory.st_mode)
        assert stat.S_IMODE(directory.st_mode) == 0o700
        assert stat.S_ISSOCK(sock.st_mode)
        assert stat.S_IMODE(sock.st_mode) == 0o600
        assert directory.st_uid == sock.st_uid == os.getuid()
    assert not path.exists()
    assert stat.S_IMODE(os.lstat(path.parent).st_mode) == 0o700  # the directory stays


async def test_without_the_option_nothing_is_served(runtime_dir: Path, sim: Simulator) -> None:
    pty = sim.open_pty()
    async with galileo.connect(pty):
        assert not (runtime_dir / DIRECTORY_NAME).exists()
        with pytest.raises(NoOwner):
            await ask_owner(pty, "stop")


async def test_a_link_to_the_device_meets_the_same_owner(runtime_dir: Path, sim: Simulator) -> None:
    pty = sim.open_pty()
    alias = runtime_dir / "galileo"  # as udev's /dev/galileo names /dev/ttyUSB0
    alias.symlink_to(pty)
    assert control_key(str(alias)) == control_key(pty)
    async with galileo.connect(str(alias), control_socket=True):
        assert (await ask_owner(pty, "cancel")).ok


async def test_udp_is_served_by_host_and_port(runtime_dir: Path, sim: Simulator) -> None:
    face = await sim.serve_udp()
    url = f"udp://127.0.0.1:{face.address[1]}"
    commands = received(sim)
    async with galileo.connect(url, control_socket=True):
        answer = await ask_owner(url, "stop")
        assert answer.ok, answer.fields
        assert answer.pid == os.getpid()
    assert Stop(100) in commands
    assert control_key("udp://127.0.0.1") == control_key("udp://127.0.0.1:20001")
    assert control_key("udp://[0:0::1]:5") == control_key("udp://[::1]:5")
    assert control_key("udp://Robot.local") == control_key("udp://robot.local:20001")


@pytest.mark.parametrize(
    "url",
    ["sim://", "socket://127.0.0.1:4000", "ros://127.0.0.1:11311", "http://127.0.0.1:3546",
     "rfc2217://127.0.0.1:4000", "loop://"],
)  # fmt: skip
def test_ports_that_others_can_open_have_no_control_socket(url: str) -> None:
    assert control_key(url) is None


# --- the server on its own ------------------------------------------------------------------


async def test_a_process_of_another_user_is_refused(
    runtime_dir: Path, caplog: pytest.LogCaptureFixture
) -> None:
    operations = Operations()
    stranger = Peer(pid=4242, uid=os.getuid() + 1, gid=0)
    url = fake_port(runtime_dir)
    caplog.set_level(logging.WARNING, SERVER_LOG)
    async with serving(url, operations, credentials=lambda _sock: stranger):
        answer = await ask_owner(url, "stop")
    assert not answer.ok
    assert answer.error == "PermissionError"
    assert operations.calls == []  # nothing ran
    assert f"refused process 4242 of uid {os.getuid() + 1}" in caplog.text


async def test_the_kernel_names_the_asker(runtime_dir: Path) -> None:
    seen: list[Peer] = []

    def credentials(sock: Any) -> Peer:
        seen.append(control_server.peer_credentials(sock))
        return seen[-1]

    url = fake_port(runtime_dir)
    async with serving(url, Operations(), credentials=credentials):
        assert (await ask_owner(url, "cancel")).ok
    assert seen == [Peer(os.getpid(), os.getuid(), os.getgid())]


@pytest.mark.parametrize(
    "line",
    [b'{"op": "shutdown_host"}\n', b'{"op": "goto", "target": 3}\n', b"stop\n", b"[1, 2]\n"],
)
async def test_only_stop_cancel_and_pause_run(runtime_dir: Path, line: bytes) -> None:
    operations = Operations()
    url = fake_port(runtime_dir)
    async with serving(url, operations):
        reader, writer = await asyncio.open_unix_connection(os.fspath(path_of(url)))
        try:
            writer.write(line)
            answer = json.loads(await asyncio.wait_for(reader.readline(), WAIT))
        finally:
            writer.close()
    assert answer["ok"] is False
    assert answer["error"] == "InvalidArgument"
    assert answer["pid"] == os.getpid()
    assert operations.calls == []


async def test_a_silent_connection_is_closed(
    runtime_dir: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(control_server, "REQUEST_TIMEOUT", 0.1)
    url = fake_port(runtime_dir)
    async with serving(url, Operations()):
        reader, writer = await asyncio.open_unix_connection(os.fspath(path_of(url)))
        try:
            assert await asyncio.wait_for(reader.read(), WAIT) == b""  # closed, no answer
        finally:
            writer.close()


def stale_socket(path: Path) -> None:
    """A socket file whose process ended without removing it: connecting is refused."""
    path.parent.mkdir(mode=0o700, exist_ok=True)
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as dead:
        dead.bind(os.fspath(path))
    assert stat.S_ISSOCK(os.lstat(path).st_mode)


async def test_a_stale_socket_file_is_replaced(
    runtime_dir: Path, sim: Simulator, caplog: pytest.LogCaptureFixture
) -> None:
    pty = sim.open_pty()
    stale_socket(path_of(pty))
    with pytest.raises(NoOwner, match="stale"):
        await ask_owner(pty, "stop")
    caplog.set_level(logging.INFO, SERVER_LOG)
    async with galileo.connect(pty, control_socket=True):
        assert (await ask_owner(pty, "stop")).ok
    assert "replaced a stale control socket" in caplog.text
    assert not path_of(pty).exists()


async def test_a_live_owner_keeps_its_socket(
    runtime_dir: Path, caplog: pytest.LogCaptureFixture
) -> None:
    url = fake_port(runtime_dir)
    first, second = Operations(), Operations()
    async with serving(url, first):
        assert await serve_control(url, second.table()) is None
        assert f"process {os.getpid()} serves" in caplog.text
        assert (await ask_owner(url, "pause")).ok
    assert [op for op, _ in first.calls] == ["pause"]
    assert second.calls == []
    assert not path_of(url).exists()


@pytest.mark.parametrize("how", ["open", "symlink", "other"])
async def test_a_directory_that_is_not_private_is_not_used(
    runtime_dir: Path, how: str, caplog: pytest.LogCaptureFixture
) -> None:
    url = fake_port(runtime_dir)
    directory = path_of(url).parent
    if how == "open":
        directory.mkdir(mode=0o700)
        directory.chmod(0o755)
        why = "open to other users (mode 0755"
    elif how == "symlink":
        elsewhere = runtime_dir / "elsewhere"
        elsewhere.mkdir(mode=0o700)
        directory.symlink_to(elsewhere)
        why = "is not a directory (a symlink?)"
    else:
        if os.getuid() != 0:
            pytest.skip("giving a directory to another user needs root")
        directory.mkdir(mode=0o700)
        os.chown(directory, 4242, -1)
        why = "belongs to uid 4242"
    assert await serve_control(url, Operations().table()) is None
    assert why in caplog.text
    with pytest.raises(ControlUnavailable, match=re.escape(why)):
        await ask_owner(url, "stop")


# --- every exit path ------------------------------------------------------------------------


@pytest.mark.parametrize("how", ["normal", "exception", *WAYS])
async def test_the_socket_is_removed_on_every_exit(
    runtime_dir: Path, sim: Simulator, how: str
) -> None:
    pty = sim.open_pty()
    served = asyncio.Event()

    async def owner() -> None:
        async with galileo.connect(pty, control_socket=True):
            assert path_of(pty).exists()
            served.set()
            if how == "exception":
                raise RuntimeError("the application failed")
            if how != "normal":
                await asyncio.Event().wait()

    if how == "normal":
        await owner()
    elif how == "exception":
        with pytest.raises(RuntimeError, match="application failed"):
            await owner()
    else:
        await stop_waiting(how, owner, 1.0)
    assert served.is_set()
    assert not path_of(pty).exists()
    with pytest.raises(NoOwner):
        await ask_owner(pty, "stop")
    async with galileo.connect(pty) as again:  # and the port is free again
        assert again.status is not None


def open_descriptors() -> set[str]:
    return set(os.listdir("/proc/self/fd"))


@pytest.mark.parametrize("how", WAYS)
async def test_cancelling_the_asker_leaves_nothing_open(runtime_dir: Path, how: str) -> None:
    operations = Operations()
    operations.hold = True
    url = fake_port(runtime_dir)
    async with serving(url, operations):
        before = open_descriptors()
        await stop_waiting(how, lambda: ask_owner(url, "stop"), 0.5)
        assert operations.started.is_set()
        # The asker's end closes on the loop's next turns; the owner's stays while it runs.
        await until(lambda: len(open_descriptors() - before) == 1)
        operations.release.set()  # the owner's stop still runs to its end, then closes
        await asyncio.wait_for(operations.finished.wait(), WAIT)
        await until(lambda: open_descriptors() <= before)


async def until(condition: Callable[[], bool], turns: int = 50) -> None:
    """Give the loop up to ``turns`` turns for ``condition`` (closing transports) to hold."""
    for _ in range(turns):
        if condition():
            return
        await asyncio.sleep(0)
    assert condition()


async def test_a_request_running_when_the_owner_closes_is_answered(
    runtime_dir: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(control_server, "CLOSE_GRACE", 0.1)  # this one never ends by itself
    operations = Operations()
    operations.hold = True
    url = fake_port(runtime_dir)
    server = await serve_control(url, operations.table())
    assert server is not None
    asking = asyncio.ensure_future(ask_owner(url, "stop"))
    try:
        await asyncio.wait_for(operations.started.wait(), WAIT)
    finally:
        await server.close()
    answer = await asyncio.wait_for(asking, WAIT)
    assert not answer.ok
    assert answer.error == "ConnectionLost"
    assert "closed before the operation ended" in answer.message
    assert not path_of(url).exists()


async def test_an_owner_that_does_not_answer_is_a_timeout(
    runtime_dir: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # A process whose event loop is blocked: the kernel accepts, nothing ever answers.
    monkeypatch.setattr(control, "ANSWER_MARGIN", 0.2)
    url = fake_port(runtime_dir)
    path = path_of(url)
    path.parent.mkdir(mode=0o700)
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as blocked:
        blocked.bind(os.fspath(path))
        blocked.listen()
        with pytest.raises(galileo.GalileoTimeout) as info:
            await ask_owner(url, "stop", timeout=0.1)
    message = str(info.value)
    assert f"the process that owns {url} (pid {os.getpid()}) did not answer stop" in message
    assert "event loop may be blocked" in message


def test_a_logged_command_line_is_one_printable_line() -> None:
    line = control.command_line(None, ["galileo", "stop\nWARNING forged", "a b"])
    assert line == "galileo 'stop\\nWARNING forged' 'a b'"
    first = Path(f"/proc/{os.getpid()}/cmdline").read_bytes().split(b"\0")[0].decode()
    assert control.command_line(os.getpid()).startswith(shlex.quote(first))  # the kernel's
    assert control.command_line(None, None) == "?"


async def test_a_stop_that_ends_the_owners_goal_is_answered(runtime_dir: Path) -> None:
    # The asked stop() ends the owner's goto at once, and the owner leaves its block while
    # that stop still writes and waits for the robot to show it: both must still happen.
    async with Simulator(speed=20, max_speed=0.05) as sim:
        pty = sim.open_pty()
        commands = received(sim)
        working = asyncio.Event()
        owner_ended: list[BaseException] = []

        async def owner() -> None:
            async with galileo.connect(pty, control_socket=True) as robot:
                await robot.start_navigation()
                goal = asyncio.ensure_future(robot.goto(0))
                await robot.wait_until(lambda s: s.target_status == TargetStatus.WORKING)
                working.set()
                try:
                    await goal
                except galileo.GoalCancelled as exc:
                    owner_ended.append(exc)

        running = asyncio.ensure_future(owner())
        try:
            await asyncio.wait_for(working.wait(), WAIT)
            answer = await ask_owner(pty, "stop")
        finally:
            await asyncio.wait_for(running, WAIT)
    assert answer.ok, answer.fields
    assert answer.fields["done"].startswith("goal 0 cancelled")
    assert [getattr(exc, "cancelled_by", None) for exc in owner_ended] == ["stop()"]
    assert commands[-2:] == [Cancel(), Stop(100)]
    assert not path_of(pty).exists()
