"""robot.http.set_navigation_speed against the simulator's HTTP face; no robot.http elsewhere."""

from __future__ import annotations

import math

import pytest

import galileo_async as galileo
from galileo_async import InvalidArgument
from galileo_async.testing import SimulatedDevice
from tests.links.test_http_link import WAIT, http_of, navigating, robot_on_http
from tests.support.sim_integration import speeds_of

pytestmark = pytest.mark.timeout(60)


async def test_navigation_speed_reaches_the_sim_and_limits_goals() -> None:
    async with robot_on_http() as (_, robot, face):
        assert await http_of(robot).navigation_speed() == pytest.approx(0.8)
        assert await http_of(robot).set_navigation_speed(0.1) == pytest.approx(0.1)
        assert face.device.model.navigation_speed == pytest.approx(0.1)
        assert await http_of(robot).navigation_speed() == pytest.approx(0.1)
        await navigating(robot)
        async with speeds_of(robot) as speeds:
            await robot.goto(0, timeout=WAIT * 3)
        assert max(speeds) > 0.05  # it did drive
        assert max(speeds) <= 0.1 + 1e-6


async def test_bad_navigation_speeds_rejected_before_sending() -> None:
    async with robot_on_http() as (_, robot, face):
        before = face.requests
        for bad in (math.nan, -0.1, 0.0, math.inf, "fast", True):
            with pytest.raises(InvalidArgument):
                await http_of(robot).set_navigation_speed(bad)  # type: ignore[arg-type]
        assert face.requests == before


async def test_navigation_speed_is_an_http_call_only(
    galileo_robot: galileo.Robot, galileo_device: SimulatedDevice
) -> None:
    # The simulated robot of galileo_async.testing, over sim://: no HTTP API behind it.
    assert galileo_robot.http is None
    assert galileo_device.commands == []
