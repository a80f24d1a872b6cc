"""drive() over ros://: a geometry_msgs/Twist on /cmd_vel at the rate, a zero Twist at exit.

A real ROS 1 master, the rospy robot node, and a rospy /cmd_vel listener
(tests/support/ros_cmd_vel_listener.py) that prints every Twist it receives.
"""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import AsyncIterator
from pathlib import Path

import pytest

from galileo_async.robot import Robot, connect
from tests.support.ros_support import (
    START_TIMEOUT,
    SYSTEM_PYTHON,
    RobotNode,
    RosMaster,
    open_log,
    ros_env,
    stop_process,
)

pytestmark = pytest.mark.timeout(60)

LISTENER = str(Path(__file__).parents[1] / "support" / "ros_cmd_vel_listener.py")


class Listener:
    """The /cmd_vel listener's Twists, read line by line from its output."""

    def __init__(self, proc: asyncio.subprocess.Process) -> None:
        self.proc = proc

    async def next(self, timeout: float = START_TIMEOUT) -> tuple[float, float]:
        """The next Twist received: (linear.x, angular.z)."""
        assert self.proc.stdout is not None
        line = await asyncio.wait_for(self.proc.stdout.readline(), timeout)
        kind, linear, angular = line.split()
        assert kind == b"TWIST", line
        return float(linear), float(angular)


@contextlib.asynccontextmanager
async def listening(master: RosMaster) -> AsyncIterator[Listener]:
    log = open_log(master.tmp_path / "cmd-vel-listener.log")
    try:
        proc = await asyncio.create_subprocess_exec(
            SYSTEM_PYTHON, LISTENER, stdin=asyncio.subprocess.PIPE,
            stdout=asyncio.subprocess.PIPE, stderr=log, env=ros_env(master.tmp_path, master.port),
        )  # fmt: skip
    finally:
        log.close()
    try:
        assert proc.stdout is not None
        assert await asyncio.wait_for(proc.stdout.readline(), START_TIMEOUT) == b"READY\n"
        yield Listener(proc)
    finally:
        if proc.stdin is not None:
            proc.stdin.close()
        await stop_process(proc)


@contextlib.asynccontextmanager
async def robot_and_listener(tmp_path: Path) -> AsyncIterator[tuple[Robot, Listener]]:
    """A ROS master, the robot node, a /cmd_vel listener and a Robot on ros://."""
    async with (
        RosMaster.running(tmp_path) as master,
        RobotNode.running(master),
        listening(master) as listener,
        connect(master.url, connect_timeout=5.0) as robot,
    ):
        yield robot, listener


async def test_drive_publishes_twists_at_the_rate_and_a_zero_twist_at_exit(
    tmp_path: Path,
) -> None:
    async with robot_and_listener(tmp_path) as (robot, listener):
        async with robot.drive(0.3, -0.5, rate=10):
            assert await listener.next() == (0.3, -0.5)  # the subscriber is connected
            loop = asyncio.get_running_loop()
            started = loop.time()
            count = 0
            while loop.time() - started < 1.0:
                assert await listener.next(timeout=1.0) == (0.3, -0.5)
                count += 1
        assert 7 <= count <= 13, count  # 10 Hz for 1 s
        assert await listener.next() == (0.0, 0.0)
        with pytest.raises(asyncio.TimeoutError):  # nothing after the stop
            await listener.next(timeout=0.3)


async def test_stop_inside_drive_publishes_one_zero_twist_and_ends_the_session(
    tmp_path: Path,
) -> None:
    async with robot_and_listener(tmp_path) as (robot, listener):
        await robot.start_navigation(timeout=10)
        async with robot.drive(0.3, 0.0, rate=10) as session:
            assert await listener.next() == (0.3, 0.0)  # the subscriber is connected
            report = await robot.stop()
            assert report.drive
            assert not session.active
            # Twists already on the wire may still arrive; then the zero one, then nothing.
            while await listener.next() != (0.0, 0.0):
                pass
            with pytest.raises(asyncio.TimeoutError):
                await listener.next(timeout=0.5)
        with pytest.raises(asyncio.TimeoutError):  # leaving the block adds nothing
            await listener.next(timeout=0.3)
