"""Every way a goal ends, over a real link: goto() and events() give it the same name."""

from __future__ import annotations

import asyncio
from typing import Any

import anyio
import pytest

import galileo_async as galileo
from galileo_async import GoalCancelled, GoalError, GoalRejected, GoalResult
from galileo_async import events as ev
from galileo_async.protocol import Cancel, Goto
from galileo_async.sim import Simulator
from tests.support.scripted_robot import ENDLESS, REACTION_FRAMES, ScriptedRobot, connected, working
from tests.support.sim_integration import SPEED, WAIT

WORKING = {"target_num_id": 3, "target_status": 1, "target_distance": 1.0}

#: After ``g 3``: the fields the robot shows, step by step, and the end's one name.
ENDINGS: dict[str, tuple[list[dict[str, Any]], str]] = {
    "reached": ([WORKING, {"target_status": 0, "target_distance": 0.0}], "GoalReached"),
    "free far from the target": (
        [WORKING | {"target_distance": 2.0}, {"target_status": 0}],
        "GoalAborted",
    ),
    "rejected by the firmware: -1, id unchanged": ([{"target_status": -1}], "GoalRejected"),
    "rejected as the document's 3, id updated": (
        [{"target_num_id": 3, "target_status": 3}],
        "GoalRejected",
    ),
    "error while moving": ([WORKING, {"target_status": -1}], "GoalRejected"),
    "cancelled on the robot": (
        [WORKING, {"target_num_id": -1, "target_status": 0}],
        "GoalCancelled",
    ),
    "preempted by a goal from elsewhere": ([WORKING, {"target_num_id": 5}], "GoalCancelled"),
    "navigation closed, the goal still working": ([WORKING, {"nav_status": 0}], "GoalCancelled"),
    "navigation closed and the goal freed in place": (
        [WORKING, {"nav_status": 0, "target_status": 0}],
        "GoalCancelled",
    ),
    "navigation closed and the goal freed": (
        [WORKING, {"nav_status": 0, "target_num_id": -1, "target_status": 0}],
        "GoalCancelled",
    ),
}


def scripted(steps: list[dict[str, Any]]) -> Any:
    async def script(fake: ScriptedRobot, command: Goto) -> None:
        await fake.frames(REACTION_FRAMES)
        for fields in steps:
            fake.set(**fields)
            await fake.frames(3)

    return script


async def goto_ending(robot: galileo.Robot, target_id: int) -> str:
    try:
        result = await robot.goto(target_id, timeout=5)
    except GoalError as exc:
        return type(exc).__name__
    assert isinstance(result, GoalResult)
    return "GoalReached"


async def event_ending(events: Any, target_id: int) -> str:
    ends = (ev.GoalReached, ev.GoalAbortedEvent, ev.GoalRejectedEvent, ev.GoalCancelledEvent)
    async for event in events:
        if isinstance(event, ends) and event.target_id == target_id:
            return event.name
    raise AssertionError("events() ended without the goal's end")


@pytest.mark.parametrize("case", list(ENDINGS))
async def test_goto_and_events_name_each_ending_alike(case: str) -> None:
    steps, name = ENDINGS[case]
    fake = ScriptedRobot()
    fake.scripts[Goto] = scripted(steps)
    async with connected(fake) as (robot, _):
        events = robot.events()  # subscribed before the goal is sent
        try:
            with anyio.fail_after(5):
                by_goto = await goto_ending(robot, 3)
                by_events = await event_ending(events, 3)
        finally:
            await events.aclose()
    assert (by_goto, by_events) == (name, name)


async def test_a_rejected_goal_is_reported_with_its_own_id() -> None:
    # goto(1) runs; goto(42) is rejected as -1 with the id left at 1 (docs/protocol.md §2.b).
    async with connected(ScriptedRobot(**ENDLESS)) as (robot, _):
        events = robot.events()
        try:
            first = asyncio.create_task(robot.goto(1, timeout=5))
            await working(robot, 1)
            with anyio.fail_after(5):
                with pytest.raises(GoalRejected) as rejected:
                    await robot.goto(42, timeout=5)
                with pytest.raises(GoalCancelled) as preempted:
                    await first
                seen: list[ev.Event] = []
                async for event in events:
                    seen.append(event)
                    if isinstance(event, ev.GoalRejectedEvent):
                        break
        finally:
            await events.aclose()
    assert (rejected.value.target_id, preempted.value.preempted) == (42, True)
    goal_ends = [
        (e.name, e.target_id)
        for e in seen
        if isinstance(e, ev.GoalEvent) and e.name != "GoalAccepted"
    ]
    assert goal_ends == [("GoalCancelled", 1), ("GoalRejected", 42)]


async def test_a_restarted_simulator_is_no_goal_failure_for_a_watcher() -> None:
    async with Simulator(speed=SPEED) as first:
        server = await first.serve_tcp()
        port = server.sockets[0].getsockname()[1]
        options: dict[str, Any] = {"reconnect_initial": 0.01, "stale_timeout": None}
        async with galileo.connect(f"socket://127.0.0.1:{port}", **options) as robot:
            await robot.start_navigation(timeout=WAIT)
            await robot.goto(0, timeout=WAIT)
            events = robot.events()
            try:
                await first.close()
                async with Simulator(speed=SPEED) as second:
                    await second.serve_tcp(port=port)
                    with anyio.fail_after(WAIT):
                        seen: list[ev.Event] = []
                        async for event in events:
                            seen.append(event)
                            if isinstance(event, ev.ConnectionRestored):
                                break
                        # The restarted robot's first status is seen: navigation opens after it.
                        await robot.start_navigation(timeout=WAIT)
                        async for event in events:
                            seen.append(event)
                            if isinstance(event, ev.NavigationOpened):
                                break
            finally:
                await events.aclose()
    assert [e for e in seen if isinstance(e, ev.GoalRejectedEvent)] == []


async def test_robot_cancel_is_a_cancel_for_goto_and_events_alike() -> None:
    # The document's cancel frees the goal in place (only real firmware sets the id to -1).
    async def cancel_in_place(fake: ScriptedRobot, command: Any) -> None:
        await fake.frames(REACTION_FRAMES)
        fake.stop_motion()
        fake.set(target_status=0)

    fake = ScriptedRobot(**ENDLESS)
    fake.scripts[Cancel] = cancel_in_place
    async with connected(fake) as (robot, _):
        events = robot.events()
        try:
            with anyio.fail_after(5):
                goal = asyncio.create_task(goto_ending(robot, 3))
                await working(robot, 3)
                await robot.cancel(timeout=5)
                by_goto = await goal
                by_events = await event_ending(events, 3)
        finally:
            await events.aclose()
    assert (by_goto, by_events) == ("GoalCancelled", "GoalCancelled")
