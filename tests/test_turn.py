"""turn_to: a turn in place by drive(), closed loop on current_angle, on firmware ignoring 'a'."""

from __future__ import annotations

import anyio
import pytest

import galileo_async as galileo
from galileo_async.errors import CommandSuperseded, UnconfirmedOperation

WAIT = 20.0


def off(robot: galileo.Robot, degrees: float) -> float:
    """Degrees between the robot's heading and ``degrees``."""
    status = robot.status
    assert status is not None
    assert status.pose is not None
    return abs((status.pose.degrees - degrees + 180.0) % 360.0 - 180.0)


async def test_turn_to_reaches_the_heading_and_stops() -> None:
    async with galileo.connect("sim://?speed=5") as robot:
        await robot.start_navigation()
        await robot.turn_to(90.0, timeout=WAIT)
        assert off(robot, 90.0) <= robot.angle_tolerance
        await robot.wait_until(lambda s: s.current_speed_theta == 0.0, timeout=WAIT)
        assert off(robot, 90.0) <= robot.angle_tolerance + 1.0  # it stood still after


async def test_rotate_to_falls_back_to_a_turn_on_firmware_that_ignores_a() -> None:
    async with galileo.connect("sim://?speed=5") as robot:
        await robot.start_navigation()
        with pytest.raises(UnconfirmedOperation):
            await robot.rotate_to(-90.0, timeout=0.3)
        await robot.rotate_to(-90.0, timeout=WAIT / 2, fallback=True)
        assert off(robot, -90.0) <= robot.angle_tolerance


async def test_a_user_stop_ends_the_turn_and_nothing_turns_after() -> None:
    async with galileo.connect("sim://?speed=2") as robot:
        await robot.start_navigation()

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
