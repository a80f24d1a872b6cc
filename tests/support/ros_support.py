"""Helpers for the ROS tests: a real rosmaster and the rospy robot node as subprocesses."""

from __future__ import annotations

import asyncio
import contextlib
import os
import shutil
import socket
import subprocess
from collections.abc import AsyncIterator, Callable
from pathlib import Path
from typing import Any, BinaryIO

import pytest

from tests.support.peers import missing_peer

#: Debian's ROS 1 runs under the system interpreter, not the project's venv.
SYSTEM_PYTHON = "/usr/bin/python3"
NODE_SCRIPT = str(Path(__file__).with_name("ros_robot_node.py"))
START_TIMEOUT = 10.0
STOP_TIMEOUT = 3.0


def require_ros() -> str:
    """The rosmaster executable; skip when ROS 1 is missing, fail if GALILEO_REQUIRE_PEERS=1."""
    rosmaster = shutil.which("rosmaster")
    if rosmaster is None or not os.path.exists(SYSTEM_PYTHON):
        missing_peer("ROS 1")
    assert rosmaster is not None
    return rosmaster


def free_port(kind: int = socket.SOCK_STREAM) -> int:
    """A currently free port on 127.0.0.1."""
    with socket.socket(socket.AF_INET, kind) as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def open_log(path: Path) -> BinaryIO:
    """A log file for a subprocess's output (the caller closes it once the child has it)."""
    return path.open("ab")


def ros_env(tmp_path: Path, master_port: int) -> dict[str, str]:
    """Environment for ROS processes: loopback only, logs under tmp_path."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("ROS")}
    env.update(
        ROS_MASTER_URI=f"http://127.0.0.1:{master_port}/",
        ROS_IP="127.0.0.1",
        ROS_HOSTNAME="127.0.0.1",
        ROS_HOME=str(tmp_path / "ros"),
        ROS_LOG_DIR=str(tmp_path / "ros" / "log"),
        PYTHONDONTWRITEBYTECODE="1",
    )
    return env


async def stop_process(proc: asyncio.subprocess.Process) -> None:
    """Terminate, then kill after STOP_TIMEOUT; always reaps the child."""
    if proc.returncode is None:
        with contextlib.suppress(ProcessLookupError):
            proc.terminate()
        try:
            await asyncio.wait_for(proc.wait(), STOP_TIMEOUT)
        except asyncio.TimeoutError:
            with contextlib.suppress(ProcessLookupError):
                proc.kill()
            await proc.wait()


async def wait_for_port(port: int, timeout: float) -> None:
    """Wait until something accepts TCP connections on 127.0.0.1:port."""
    loop = asyncio.get_running_loop()
    deadline = loop.time() + timeout
    while True:
        try:
            _, writer = await asyncio.open_connection("127.0.0.1", port)
        except OSError:
            if loop.time() > deadline:
                raise TimeoutError(f"nothing listens on 127.0.0.1:{port}") from None
            await asyncio.sleep(0.05)  # polling a subprocess's port: there is no event to await
            continue
        writer.close()
        return


async def eventually(check: Callable[[], Any], timeout: float, what: str) -> None:
    """Poll an external condition (another process's state has no event to await)."""
    loop = asyncio.get_running_loop()
    deadline = loop.time() + timeout
    while True:
        result = check()
        if asyncio.iscoroutine(result):
            result = await result
        if result:
            return
        if loop.time() > deadline:
            pytest.fail(f"timed out waiting for {what}")
        await asyncio.sleep(0.05)


async def refuses_connections(port: int) -> bool:
    """True when nothing listens on 127.0.0.1:port any more."""
    try:
        _, writer = await asyncio.wait_for(asyncio.open_connection("127.0.0.1", port), 1.0)
    except (ConnectionRefusedError, asyncio.TimeoutError):
        return True
    writer.close()
    return False


class RosMaster:
    """A real ``rosmaster --core`` on 127.0.0.1; stop() and start() again on the same port."""

    def __init__(self, tmp_path: Path, port: int | None = None) -> None:
        self.executable = require_ros()
        self.tmp_path = tmp_path
        self.port = port or free_port()
        self.proc: asyncio.subprocess.Process | None = None

    @property
    def url(self) -> str:
        """The ros:// URL of this master."""
        return f"ros://127.0.0.1:{self.port}"

    async def start(self) -> None:
        """Start the master and wait until it accepts connections."""
        log = open_log(self.tmp_path / f"rosmaster-{self.port}.log")
        try:
            self.proc = await asyncio.create_subprocess_exec(
                self.executable, "--core", "-p", str(self.port),
                stdin=asyncio.subprocess.DEVNULL, stdout=log, stderr=log,
                env=ros_env(self.tmp_path, self.port),
            )  # fmt: skip
        finally:
            log.close()
        await wait_for_port(self.port, START_TIMEOUT)

    async def stop(self) -> None:
        """Stop the master (idempotent)."""
        if self.proc is not None:
            await stop_process(self.proc)
            self.proc = None

    @classmethod
    @contextlib.asynccontextmanager
    async def running(cls, tmp_path: Path) -> AsyncIterator[RosMaster]:
        """A started master, stopped on exit whatever happens."""
        master = cls(tmp_path)
        try:
            await master.start()
            yield master
        finally:
            await master.stop()


class RobotNode:
    """The rospy robot node (tests/support/ros_robot_node.py) under the system Python."""

    def __init__(self, master: RosMaster, *args: str) -> None:
        self.master = master
        self.args = args
        self.proc: asyncio.subprocess.Process | None = None

    async def start(self) -> None:
        """Start the node and wait for its READY line."""
        log = open_log(self.master.tmp_path / "robot-node.log")
        try:
            self.proc = await asyncio.create_subprocess_exec(
                SYSTEM_PYTHON, NODE_SCRIPT, *self.args,
                stdin=asyncio.subprocess.PIPE, stdout=asyncio.subprocess.PIPE, stderr=log,
                env=ros_env(self.master.tmp_path, self.master.port),
            )  # fmt: skip
        finally:
            log.close()
        assert self.proc.stdout is not None
        try:
            while True:
                line = await asyncio.wait_for(self.proc.stdout.readline(), START_TIMEOUT)
                if not line:
                    log_text = (self.master.tmp_path / "robot-node.log").read_text()
                    raise RuntimeError(f"robot node exited before READY:\n{log_text[-3000:]}")
                if line.startswith(b"READY"):
                    return
        except BaseException:
            await self.stop()
            raise

    async def control(self, line: str) -> None:
        """Send one control line (``busy 1.5``, ``abort``) to the node."""
        assert self.proc is not None
        assert self.proc.stdin is not None
        self.proc.stdin.write(line.encode() + b"\n")
        await self.proc.stdin.drain()

    async def stop(self) -> None:
        """Stop the node (idempotent)."""
        if self.proc is not None:
            proc, self.proc = self.proc, None
            if proc.stdin is not None:
                proc.stdin.close()
            await stop_process(proc)

    @classmethod
    @contextlib.asynccontextmanager
    async def running(cls, master: RosMaster, *args: str) -> AsyncIterator[RobotNode]:
        """A started node, stopped on exit whatever happens."""
        node = cls(master, *args)
        try:
            await node.start()
            yield node
        finally:
            await node.stop()


def genpy_script(code: str, stdin: str = "") -> str:
    """Run ``code`` with the system Python (genpy, rospy importable); return its stdout."""
    require_ros()
    result = subprocess.run(
        [SYSTEM_PYTHON, "-c", code], input=stdin, capture_output=True, text=True,
        timeout=60, check=False,
    )  # fmt: skip
    if result.returncode != 0:
        raise RuntimeError(f"system python failed:\n{result.stderr}")
    return result.stdout


__all__ = [
    "NODE_SCRIPT",
    "SYSTEM_PYTHON",
    "RobotNode",
    "RosMaster",
    "eventually",
    "free_port",
    "genpy_script",
    "refuses_connections",
    "require_ros",
    "ros_env",
    "stop_process",
    "wait_for_port",
]
