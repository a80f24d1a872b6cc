"""turn_to: a turn in place by drive(), closed loop on current_angle, on firmware ignoring 'a'.

The simulated robot of galileo_async.testing (real firmware: it ignores 'a') on a virtual
clock; times are virtual seconds.
"""

from __future__ import annotations

import asyncio

import anyio
import pytest

import galileo_async as galileo
from galileo_async.errors import CommandSuperseded, UnconfirmedOperation

#: Bound, in virtual seconds, on a turn (half a turn takes about 2 s).
WAIT = 20.0
#: How long rotate_to waits for the 'a' the firmware ignores.
ROTATE_WAIT = 1.5


def off(robot: galileo.Robot, degrees: float) -> float:
    """Degrees between the robot's heading and ``degrees``."""
    status = robot.status
    assert status is not None
    assert status.pose is not None
    return abs((status.pose.degrees - degrees + 180.0) % 360.0 - 180.0)


async def test_turn_to_reaches_the_heading_and_stops(galileo_robot: galileo.Robot) -> None:
    robot = galileo_robot
    await robot.turn_to(90.0, timeout=WAIT)
    assert off(robot, 90.0) <= robot.angle_tolerance
    await robot.wait_until(lambda s: s.current_speed_theta == 0.0, timeout=WAIT)
    assert off(robot, 90.0) <= robot.angle_tolerance + 1.0  # it stood still after


async def test_rotate_to_falls_back_to_a_turn_on_firmware_that_ignores_a(
    galileo_robot: galileo.Robot,
) -> None:
    robot = galileo_robot
    loop = asyncio.get_running_loop()
    called_at = loop.time()
    with pytest.raises(UnconfirmedOperation):
        await robot.rotate_to(-90.0, timeout=ROTATE_WAIT)
    assert loop.time() - called_at == pytest.approx(ROTATE_WAIT)  # its own timeout, no more
    await robot.rotate_to(-90.0, timeout=WAIT / 2, fallback=True)
    assert off(robot, -90.0) <= robot.angle_tolerance


async def test_a_user_stop_ends_the_turn_and_nothing_turns_after(
    galileo_robot: galileo.Robot,
) -> None:
    robot = galileo_robot

    async def stop_once_turning() -> None:
        await robot.wait_until(lambda s: abs(s.current_speed_theta or 0.0) > 0.1)
        await robot.stop()

    with anyio.fail_after(WAIT):
        async with anyio.create_task_group() as group:
            group.start_soon(stop_once_turning)
            with pytest.raises(CommandSuperseded):
                await robot.turn_to(180.0, timeout=WAIT)
    await robot.wait_until(lambda s: s.current_speed_theta == 0.0, timeout=WAIT)
    assert off(robot, 180.0) > robot.angle_tolerance
