"""A Robot is bound to the event loop that connected it (issue #14 item 6)."""

from __future__ import annotations

import asyncio
import inspect
from collections.abc import Callable
from typing import Any

import pytest

import galileo_async as galileo
from galileo_async.errors import GalileoError, WrongEventLoop
from galileo_async.missions import Mission
from galileo_async.protocol import Stop
from tests.support.scripted_robot import connected, nothing_was_sent_before_marker

#: Valid arguments for every public method that takes any.
ARGUMENTS: dict[str, tuple[Any, ...]] = {
    "goto": (1,),
    "goto_point": (1.0, 2.0),
    "add_target": (1.0, 2.0),
    "rotate_to": (90.0,),
    "turn_to": (90.0,),
    "forward": (50,),
    "backward": (50,),
    "turn_left": (50,),
    "turn_right": (50,),
    "set_patrol_dwell": (5,),
    "send": (Stop(100),),
    "wait_until": (lambda _status: True,),
    "wait_link": (galileo.LinkState.UP,),
    "add_update_listener": (print,),
    "remove_update_listener": (print,),
    "add_event_listener": (print,),
    "remove_event_listener": (print,),
    "add_stop_listener": (print,),
    "add_raw_listener": (print,),
    "remove_raw_listener": (print,),
    "remove_stop_listener": (print,),
    "run_mission": (Mission.model_validate({"mission": "m", "steps": [{"dwell": 1}]}),),
}
KEYWORDS: dict[str, dict[str, Any]] = {"shutdown_host": {"confirm": True}}


def public_coroutines() -> list[str]:
    """Names of every public coroutine method of Robot."""
    return sorted(
        name
        for name, member in inspect.getmembers(galileo.Robot)
        if not name.startswith("_") and inspect.iscoroutinefunction(member)
    )


def call(robot: galileo.Robot, name: str) -> Any:
    method: Callable[..., Any] = getattr(robot, name)
    return method(*ARGUMENTS.get(name, ()), **KEYWORDS.get(name, {}))


def in_another_loop(robot: galileo.Robot, name: str) -> BaseException | None:
    """Run one call of ``name`` on a new event loop (in this worker thread); its error."""

    async def attempt() -> None:
        result = call(robot, name)
        if inspect.isawaitable(result):
            await asyncio.wait_for(result, 2.0)

    try:
        asyncio.run(attempt())
    except BaseException as exc:  # returned for the test to inspect
        return exc
    return None


def test_every_public_method_is_covered() -> None:
    names = public_coroutines()
    assert "goto" in names
    assert "close" in names
    assert "wait_until" in names
    for name, member in inspect.getmembers(galileo.Robot, inspect.isfunction):
        parameters = list(inspect.signature(member).parameters.values())[1:]
        needed = [p for p in parameters if p.default is p.empty and p.kind is p.KEYWORD_ONLY]
        needed += [
            p for p in parameters if p.default is p.empty and p.kind is p.POSITIONAL_OR_KEYWORD
        ]
        if not name.startswith("_") and needed:
            assert name in ARGUMENTS, f"give {name} sample arguments"


@pytest.mark.parametrize("name", [*public_coroutines(), "statuses", "events"])
async def test_call_from_another_loop_raises_at_once_and_sends_nothing(name: str) -> None:
    async with connected() as (robot, fake):
        error = await asyncio.to_thread(in_another_loop, robot, name)
        assert isinstance(error, WrongEventLoop), error
        assert isinstance(error, GalileoError)
        assert "event loop" in str(error)
        assert not robot.closed
        await nothing_was_sent_before_marker(robot, fake)


@pytest.mark.parametrize("name", ["statuses", "events"])
async def test_call_from_a_thread_without_loop_raises(name: str) -> None:
    async with connected() as (robot, _fake):
        with pytest.raises(WrongEventLoop, match="no event loop"):
            await asyncio.to_thread(call, robot, name)


async def test_the_robot_keeps_working_on_its_own_loop_after_misuse() -> None:
    async with connected() as (robot, fake):
        error = await asyncio.to_thread(in_another_loop, robot, "pause")
        assert isinstance(error, WrongEventLoop)
        await robot.stop()
        await fake.command(Stop)
