"""simulated_robot() and device.advance() left every way a caller stops waiting (cancel_ways)."""

from __future__ import annotations

import asyncio
import time
from typing import Any

import pytest

from galileo_async.robot.runtime import OPEN_ROBOTS
from galileo_async.testing import VirtualClock, simulated_fleet, simulated_robot
from tests.support.cancel_ways import WAYS, stop_waiting

#: Virtual seconds after which the wait is stopped: entering (before the first await),
#: connecting (waiting for the first status), and half way through a 7 s goal.
MOMENTS = {"entering": 0.0, "connecting": 0.01, "driving": 2.0}


def assert_released(loop: asyncio.AbstractEventLoop, robots: set[object]) -> None:
    """No Robot opened since ``robots`` is open, and the loop's time follows real time again."""
    assert set(OPEN_ROBOTS) <= robots
    assert VirtualClock.of(loop) is None
    real_start = time.monotonic()
    loop_start = loop.time()
    while time.monotonic() < real_start + 0.01:  # busy: a virtual clock stands still meanwhile
        pass
    loop_elapsed = loop.time() - loop_start
    assert 0.009 <= loop_elapsed <= time.monotonic() - real_start


@pytest.mark.parametrize("moment", list(MOMENTS))
@pytest.mark.parametrize("how", WAYS)
async def test_simulated_robot_releases_everything_however_it_is_left(
    how: str, moment: str
) -> None:
    loop = asyncio.get_running_loop()
    robots = set(OPEN_ROBOTS)
    reached: list[str] = []

    async def use() -> None:
        async with simulated_robot() as (robot, _device):
            reached.append("inside")
            await robot.goto(2)  # 5 m away: still driving at 2 s
            reached.append("arrived")

    await stop_waiting(how, use, MOMENTS[moment])
    assert "arrived" not in reached
    if moment == "driving":
        assert reached == ["inside"]
    assert_released(loop, robots)


@pytest.mark.parametrize("how", WAYS)
async def test_a_stopped_advance_stops_the_clock_there_and_the_robot_goes_on(how: str) -> None:
    loop = asyncio.get_running_loop()
    robots = set(OPEN_ROBOTS)
    async with simulated_robot() as (robot, device):
        start = loop.time()
        await stop_waiting(how, lambda: device.advance(100.0), 3.0)
        assert loop.time() - start == pytest.approx(3.0, abs=1e-6)
        assert VirtualClock.of(loop) is not None  # still inside: still virtual
        assert (await robot.goto(0)).target_id == 0
        await device.advance(1.0)
    assert_released(loop, robots)


@pytest.mark.parametrize("which", ["robot", "fleet"])
@pytest.mark.parametrize("times", [1, 2])
async def test_leaving_cancelled_while_it_closes_still_releases_everything(
    which: str, times: int
) -> None:
    # The block's exit (Robot.close(), the simulator's close, the clock's release) is
    # cancelled once or twice more while it runs: it finishes, then the cancellation goes on.
    loop = asyncio.get_running_loop()
    robots = set(OPEN_ROBOTS)
    closed: list[bool] = []

    async def use() -> None:
        task = asyncio.current_task()
        assert task is not None
        if which == "robot":
            context: Any = simulated_robot()
        else:
            context = simulated_fleet(2)
        async with context as (handle, _):
            if which == "fleet":
                handle = handle.get("robot1")
            await handle.goto(1)
            # Land while the exit runs (at its first wait, and 1 ms into it), not before it.
            loop.call_soon(task.cancel)
            if times == 2:
                loop.call_later(0.001, task.cancel)
        closed.append(True)

    task = asyncio.ensure_future(use())
    with pytest.raises(asyncio.CancelledError):
        await task
    assert closed == []  # the cancellation was raised after the exit, not swallowed
    assert_released(loop, robots)
