"""--start-navigation keeps navigation open across robot restarts (virtual clock, no broker)."""

from __future__ import annotations

from collections.abc import AsyncIterator
from contextlib import asynccontextmanager

import anyio
import pytest

from galileo_async.models import LinkState
from galileo_async.protocol import StartNavigation
from galileo_async.robot import Robot
from galileo_async.testing import SimulatedDevice, simulated_robot
from galileo_async.vda5050 import Vehicle, VehicleConfig
from galileo_async.vda5050.vehicle import NAVIGATION_RETRY_INITIAL

#: Seconds of virtual time a test waits for what it expects.
WAIT = 120.0


@asynccontextmanager
async def kept_vehicle(
    navigating: bool = False, start_ignore_time: float = 0.0
) -> AsyncIterator[tuple[Robot, SimulatedDevice, Vehicle]]:
    """A vehicle with start_navigation on a simulated robot, no broker reachable."""
    options = {"start_ignore_time": start_ignore_time}
    async with simulated_robot(navigating=navigating, sim_options=options) as (robot, device):
        config = VehicleConfig(
            broker="mqtt://127.0.0.1:1", manufacturer="acme", serial_number="nav",
            start_navigation=True, visualization_rate=0.0,
        )  # fmt: skip
        vehicle = Vehicle(robot, config)
        async with anyio.create_task_group() as group:
            group.start_soon(vehicle.run)
            try:
                yield robot, device, vehicle
            finally:
                group.cancel_scope.cancel()


def starts(device: SimulatedDevice) -> int:
    return len(device.received(StartNavigation))


async def test_navigation_is_opened_again_after_the_robot_restarts_behind_a_lost_link(
    caplog: pytest.LogCaptureFixture,
) -> None:
    async with kept_vehicle() as (robot, device, _vehicle):
        await robot.wait_until(lambda s: s.navigating and s.visual_initialised, timeout=WAIT)
        assert starts(device) == 1
        device.drop_link()  # the robot restarts: its link goes, navigation closes
        await robot.wait_link(LinkState.LOST, timeout=WAIT)
        device.set(nav_status=0, visual_status=0)
        device.restore_link()
        await robot.wait_link(LinkState.UP, timeout=WAIT)
        await robot.wait_until(lambda s: s.navigating and s.visual_initialised, timeout=WAIT)
        assert starts(device) == 2
    assert "opening the robot's navigation" in caplog.text


async def test_navigation_closed_by_a_restart_on_a_live_link_is_opened_again() -> None:
    async with kept_vehicle(navigating=True) as (robot, device, _vehicle):
        await robot.wait_until(lambda s: s.navigating, timeout=WAIT)
        device.set(nav_status=0, visual_status=0)  # the navigation system restarted
        await device.next_command(StartNavigation, timeout=WAIT)
        await robot.wait_until(lambda s: s.navigating and s.visual_initialised, timeout=WAIT)
        assert starts(device) == 1


async def test_a_failed_start_is_retried_with_back_off() -> None:
    async with kept_vehicle(navigating=True, start_ignore_time=100.0) as (robot, device, _):
        await robot.wait_until(lambda s: s.navigating, timeout=WAIT)
        device.lock_out_start()  # the firmware ignores a start within 100 s: starts fail
        device.set(nav_status=0, visual_status=0)
        first = await device.next_command(StartNavigation, timeout=WAIT)
        second = await device.next_command(StartNavigation, timeout=WAIT)
        third = await device.next_command(StartNavigation, timeout=WAIT)
        # Each try waits for its confirmation, then the back-off, doubled after each failure
        # (times are counted in frames of 1/30 s).
        first_gap, second_gap = second.at - first.at, third.at - second.at
        assert first_gap > NAVIGATION_RETRY_INITIAL
        assert second_gap - first_gap > NAVIGATION_RETRY_INITIAL - 0.1
        await robot.wait_until(lambda s: s.navigating, timeout=10 * WAIT)


async def test_navigation_stays_closed_once_the_vehicle_shut_down() -> None:
    async with kept_vehicle(navigating=True) as (robot, device, vehicle):
        await robot.wait_until(lambda s: s.navigating, timeout=WAIT)
        await vehicle.shut_down("test")
        device.set(nav_status=0, visual_status=0)
        await device.advance(30.0)
        assert starts(device) == 0
        assert robot.status is not None
        assert not robot.status.navigating
