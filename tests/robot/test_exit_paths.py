"""Every exit path closes the connection (issue #14 items 1, 2, 5), over real links.

``sim://`` runs on the virtual clock; the socket and scripted-robot links on the real one.
"""

from __future__ import annotations

import asyncio
import contextlib
import sys
from collections.abc import AsyncIterator, Awaitable, Callable
from typing import Any

import anyio
import pytest

import galileo_async as galileo
from galileo_async.errors import GalileoConnectionError
from galileo_async.sim import Simulator
from galileo_async.testing import VirtualClock
from tests.support.scripted_robot import ScriptedRobot

STEP = 5.0  # upper bound, in real seconds, for anything expected to happen
SPEED = 20.0


class Boom(Exception):
    """The failure of a sibling task."""


@contextlib.asynccontextmanager
async def served_sim() -> AsyncIterator[tuple[Simulator, str]]:
    """A simulator served on a free loopback port, and its socket:// URL."""
    async with Simulator(speed=SPEED) as sim:
        server = await sim.serve_tcp()
        yield sim, f"socket://127.0.0.1:{server.sockets[0].getsockname()[1]}"


async def until(condition: Callable[[], bool]) -> None:
    """Wait, loop turn by loop turn and then briefly, until ``condition`` holds (bounded)."""
    with anyio.fail_after(STEP):
        while not condition():  # noqa: ASYNC110 - these counters have no event to wait on
            await asyncio.sleep(0.005)


async def assert_closed(robot: galileo.Robot, sim: Simulator | None = None) -> None:
    """The robot is closed, its transport too, and it decodes nothing any more."""
    assert robot.closed
    assert not robot.link.connected
    if sim is not None:
        await until(lambda: sim.state.connections == 0)
    frames = robot.link.frames
    # Absence of frames can only be seen over time: a few status periods of the simulator.
    await asyncio.sleep(0.05)
    assert robot.link.frames == frames


# --- item 1: close() finishes when its caller is cancelled --------------------------------


@pytest.mark.parametrize("turns", range(1, 9))
async def test_cancelled_close_still_closes_the_transport(turns: int) -> None:
    async with served_sim() as (sim, url):
        robot = await galileo.connect(url)
        await until(lambda: sim.state.connections == 1)
        closing = asyncio.create_task(robot.close())
        for _ in range(turns):
            await asyncio.sleep(0)
        closing.cancel()
        with pytest.raises(asyncio.CancelledError):
            await closing
        await assert_closed(robot, sim)


async def test_close_cancelled_twice_re_raises_and_closes() -> None:
    async with served_sim() as (sim, url):
        robot = await galileo.connect(url)
        closing = asyncio.create_task(robot.close())
        await asyncio.sleep(0)
        closing.cancel()
        await asyncio.sleep(0)
        closing.cancel()
        with pytest.raises(asyncio.CancelledError):
            await closing
        await assert_closed(robot, sim)
        await robot.close()  # idempotent, and prompt once done


async def test_close_inside_an_expired_anyio_scope_closes() -> None:
    async with served_sim() as (sim, url):
        robot = await galileo.connect(url)
        with anyio.CancelScope() as scope:
            scope.cancel()
            await robot.close()  # the scope is cancelled already: close runs shielded
        assert scope.cancelled_caught
        await assert_closed(robot, sim)


# --- item 2: leaving `async with connect(...)` by any route closes ------------------------


async def _normal(url: str, seen: list[galileo.Robot]) -> None:
    async with galileo.connect(url) as robot:
        seen.append(robot)


async def _raise_inside(url: str, seen: list[galileo.Robot]) -> None:
    async with galileo.connect(url) as robot:
        seen.append(robot)
        raise Boom


async def _exception(url: str, seen: list[galileo.Robot]) -> None:
    with pytest.raises(Boom):
        await _raise_inside(url, seen)


async def _forever(url: str, seen: list[galileo.Robot]) -> None:
    async with galileo.connect(url) as robot:
        seen.append(robot)
        await asyncio.Event().wait()


async def _move_on_after(url: str, seen: list[galileo.Robot]) -> None:
    with anyio.move_on_after(0.2) as scope:
        await _forever(url, seen)
    assert scope.cancelled_caught


async def _fail_after(url: str, seen: list[galileo.Robot]) -> None:
    with pytest.raises(TimeoutError):
        with anyio.fail_after(0.2):
            await _forever(url, seen)


async def _asyncio_timeout(url: str, seen: list[galileo.Robot]) -> None:
    if sys.version_info < (3, 11):
        pytest.skip("asyncio.timeout needs Python 3.11")
    with pytest.raises(TimeoutError):
        async with asyncio.timeout(0.2):
            await _forever(url, seen)


async def _fail_when(seen: list[galileo.Robot], count: int) -> None:
    await until(lambda: len(seen) == count)
    raise Boom


def has_boom(exc: BaseException) -> bool:
    """``exc`` is Boom or an exception group holding one."""
    return isinstance(exc, Boom) or any(map(has_boom, getattr(exc, "exceptions", ())))


async def _anyio_group(url: str, seen: list[galileo.Robot]) -> None:
    async with anyio.create_task_group() as group:
        for _ in range(3):
            group.start_soon(_forever, url, seen)
        group.start_soon(_fail_when, seen, 3)


async def _anyio_task_group(url: str, seen: list[galileo.Robot]) -> None:
    with pytest.raises(Exception) as caught:  # noqa: PT011 - a group or Boom: checked below
        await _anyio_group(url, seen)
    assert has_boom(caught.value)


async def _asyncio_group(url: str, seen: list[galileo.Robot]) -> None:
    async with asyncio.TaskGroup() as group:
        for _ in range(3):
            group.create_task(_forever(url, seen))
        group.create_task(_fail_when(seen, 3))


async def _asyncio_task_group(url: str, seen: list[galileo.Robot]) -> None:
    if sys.version_info < (3, 11):
        pytest.skip("asyncio.TaskGroup needs Python 3.11")
    with pytest.raises(Exception) as caught:  # noqa: PT011 - a group: checked below
        await _asyncio_group(url, seen)
    assert has_boom(caught.value)


async def _cancelled_task(url: str, seen: list[galileo.Robot]) -> None:
    task = asyncio.create_task(_forever(url, seen))
    await until(lambda: len(seen) == 1)
    task.cancel()
    with pytest.raises(asyncio.CancelledError):
        await task


ROUTES: dict[str, Callable[[str, list[galileo.Robot]], Awaitable[None]]] = {
    "normal": _normal,
    "exception": _exception,
    "anyio.move_on_after": _move_on_after,
    "anyio.fail_after": _fail_after,
    "asyncio.timeout": _asyncio_timeout,
    "anyio task group sibling": _anyio_task_group,
    "asyncio.TaskGroup sibling": _asyncio_task_group,
    "task.cancel()": _cancelled_task,
}


@pytest.mark.parametrize("route", ROUTES)
async def test_leaving_connect_over_socket_closes(route: str) -> None:
    async with served_sim() as (sim, url):
        seen: list[galileo.Robot] = []
        await ROUTES[route](url, seen)
        assert seen
        for robot in seen:
            await assert_closed(robot)
        await until(lambda: sim.state.connections == 0)


@pytest.mark.parametrize("route", ROUTES)
async def test_leaving_connect_over_sim_closes(route: str) -> None:
    # In-process only: the virtual clock runs the routes' timeouts and the sim's frames.
    clock = VirtualClock.install()
    try:
        seen: list[galileo.Robot] = []
        await ROUTES[route]("sim://", seen)
        assert seen
        for robot in seen:
            await assert_closed(robot)
    finally:
        clock.release()


# --- item 5: first_status_timeout is honoured, whatever stale_timeout is -----------------


async def test_first_frame_after_two_seconds_connects_despite_stale_timeout() -> None:
    fake = ScriptedRobot()
    fake.sending = False
    await fake.start()
    loop = asyncio.get_running_loop()
    # The robot's first frame comes 2 s after the port opens, twice the stale timeout.
    later = loop.call_later(2.0, setattr, fake, "sending", True)
    try:
        started = loop.time()
        async with galileo.connect(fake.url, first_status_timeout=5, stale_timeout=1) as robot:
            assert loop.time() - started >= 2.0
            assert robot.status is not None
            assert robot.status.power == 24.0
    finally:
        later.cancel()
        await fake.close()


async def test_no_first_frame_fails_after_first_status_timeout_and_says_so() -> None:
    fake = ScriptedRobot()
    fake.sending = False
    await fake.start()
    try:
        loop = asyncio.get_running_loop()
        started = loop.time()
        options: dict[str, Any] = {"first_status_timeout": 0.6, "stale_timeout": 0.1}
        with pytest.raises(GalileoConnectionError, match=r"within 0\.6 s") as caught:
            await galileo.connect(fake.url, **options)
        assert loop.time() - started >= 0.6
        assert fake.url.removeprefix("socket://") in str(caught.value)
    finally:
        await fake.close()
