"""rotate_to reports success only when the angle goal it sent is done (docs/protocol.md §2.g).

Real firmware ignores ``a`` and derives angle_goal_status from the goal state (0 while a
goal works, 1 once free), so a navigation goal that starts and ends while rotate_to waits
shows the 0 then 1 a rotation would: that must not be taken for the rotation. The
simulated robot of galileo_async.testing plays the robot on a virtual clock (times are
virtual seconds); a second connection to it plays another host.
"""

from __future__ import annotations

import asyncio
import contextlib
import math
from collections.abc import AsyncIterator
from typing import Any, Literal

import anyio
import pytest

import galileo_async as galileo
from galileo_async import OperationFailed, TargetStatus, UnconfirmedOperation
from galileo_async.protocol import Goto, RotateTo, Stop
from galileo_async.testing import SimulatedDevice, simulated_robot
from tests.support.sim_integration import time_limit

#: Bound, in virtual seconds, on every wait expected to succeed.
WAIT = 60.0
#: A target 1.5 m straight ahead.
TARGETS = ((1.5, 0.0),)
NEAR = 0

Firmware = Literal["real", "document"]


def now() -> float:
    return asyncio.get_running_loop().time()


def near(value: float | None, expected: float, tolerance: float = 1e-3) -> bool:
    """``value`` is a number within ``tolerance`` of ``expected``."""
    return value is not None and math.isclose(value, expected, abs_tol=tolerance)


@contextlib.asynccontextmanager
async def two_hosts(
    firmware: Firmware,
) -> AsyncIterator[tuple[SimulatedDevice, galileo.Robot, galileo.Robot]]:
    """A navigating simulated robot, this host's Robot and another host's connection."""
    async with (
        simulated_robot(firmware=firmware, targets=TARGETS) as (robot, device),
        galileo.connect(device.simulator.url) as other,
    ):
        yield device, robot, other


async def _rotating(robot: galileo.Robot, degrees: float) -> asyncio.Task[None]:
    """rotate_to(degrees) in a task, once its ``a`` is written."""
    sent = robot.link.commands_sent
    task = asyncio.create_task(robot.rotate_to(degrees, timeout=WAIT))
    await robot.wait_until(lambda _s: robot.link.commands_sent > sent, timeout=WAIT)
    return task


@pytest.mark.parametrize("firmware", ["real", "document"])
async def test_a_goal_of_this_robot_ending_while_rotate_to_waits_is_not_success(
    firmware: Firmware,
) -> None:
    async with two_hosts(firmware) as (_device, robot, _other):
        rotation = await _rotating(robot, 90)
        result = await robot.goto(NEAR, timeout=WAIT)  # works (0), then arrives (1)
        assert result.target_id == NEAR
        with anyio.fail_after(WAIT), pytest.raises(OperationFailed, match="goal 0") as caught:
            await rotation
    assert caught.value.status is not None


@pytest.mark.parametrize("firmware", ["real", "document"])
async def test_a_goal_of_another_host_while_rotate_to_waits_is_not_success(
    firmware: Firmware,
) -> None:
    async with two_hosts(firmware) as (device, robot, other):
        rotation = await _rotating(robot, 90)
        await other.send(Goto(NEAR))
        with anyio.fail_after(WAIT), pytest.raises(OperationFailed, match="navigation goal"):
            await rotation
        # The goal runs on: rotate_to does not touch it.
        await robot.wait_until(
            lambda s: s.target_num_id == NEAR and s.target_status == TargetStatus.FREE,
            timeout=WAIT,
        )
        assert near(device.pose.x, TARGETS[NEAR][0])


async def test_firmware_ignoring_a_still_times_out_with_the_documented_error() -> None:
    async with two_hosts("real") as (device, robot, _other):
        called_at = now()
        with pytest.raises(UnconfirmedOperation, match="ignore the rotate command 'a'"):
            await robot.rotate_to(90, timeout=30)
        assert now() - called_at == pytest.approx(30)  # the timeout given, no more
        assert device.pose.theta == 0.0


async def test_a_rotation_that_runs_to_its_end_is_success() -> None:
    async with two_hosts("document") as (device, robot, _other):
        await robot.rotate_to(90, timeout=WAIT)
        assert near(device.pose.theta, math.pi / 2)


async def test_rotate_to_under_a_time_limit_leaves_nothing_running() -> None:
    async with two_hosts("real") as (_device, robot, _other):
        called_at = now()
        with pytest.raises(TimeoutError):
            async with time_limit(5):
                await robot.rotate_to(90)
        assert now() - called_at == pytest.approx(5)
        with anyio.move_on_after(5) as scope:
            await robot.rotate_to(-90)
        assert scope.cancelled_caught


# --- a heading the robot already has (issue 21, item 5) ----------------------------------


@contextlib.asynccontextmanager
async def facing(
    firmware: Firmware, degrees: float, **options: Any
) -> AsyncIterator[tuple[galileo.Robot, SimulatedDevice]]:
    """A navigating simulated robot that faces ``degrees`` (nothing sent to it yet)."""
    pose = (0.0, 0.0, math.radians(degrees))
    async with simulated_robot(
        firmware=firmware, targets=TARGETS, sim_options={"start_pose": pose}, **options
    ) as (robot, device):
        yield robot, device


@pytest.mark.parametrize("firmware", ["real", "document"])
@pytest.mark.parametrize(
    ("heading", "requested"), [(180, -180), (-180, 180), (180, 179), (-179.5, 179), (0, 1.5)]
)
async def test_rotate_to_the_heading_the_robot_has_returns_at_once_without_sending(
    firmware: Firmware, heading: float, requested: float
) -> None:
    async with facing(firmware, heading) as (robot, device):
        called_at = now()
        await robot.rotate_to(requested, timeout=WAIT)
        assert now() == called_at  # at once: real firmware would leave it waiting out WAIT
        await robot.zero_speed()  # a marker: whatever was sent before it has arrived
        await robot.wait_until(lambda _s: bool(device.commands), timeout=WAIT)
        assert device.received() == [Stop(100)]


async def test_a_heading_outside_the_angle_tolerance_is_rotated_to() -> None:
    async with facing("document", 180, angle_tolerance=0.5) as (robot, device):
        await robot.rotate_to(-179, timeout=WAIT)
        assert device.received() == [RotateTo(-179)]
        assert robot.status is not None
        assert robot.status.pose is not None
        assert near(robot.status.pose.degrees, -179, 0.01)
