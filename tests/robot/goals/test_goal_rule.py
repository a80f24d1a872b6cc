"""The goal rule is written once (transitions.py): goto() and events() agree on every end."""

from __future__ import annotations

from typing import Any

import anyio
import pytest

import galileo_async
from galileo_async import GalileoStatus, GoalAborted, GoalResult, TargetStatus
from galileo_async import events as ev
from galileo_async.events import Event
from galileo_async.protocol import Goto
from galileo_async.state import StatusStore
from galileo_async.transitions import (
    GoalChange,
    arrived,
    derive_events,
    end_distance,
    goal_step,
    running_distance,
    valid_distance,
)
from tests.support.scripted_robot import REACTION_FRAMES, ScriptedRobot, connected

WORKING, FREE = int(TargetStatus.WORKING), int(TargetStatus.FREE)

#: (target_status, target_distance) steps of goal 3, then the outcome both sides must report.
#: -1 is an invalid distance (docs/protocol.md §1): the last valid one seen while it ran counts.
ENDS: dict[str, tuple[list[tuple[int, float]], bool, float | None]] = {
    "free at -1 after 0.0 m": ([(WORKING, 1.0), (WORKING, 0.0), (FREE, -1.0)], True, 0.0),
    "-1 while working, then free at -1": (
        [(WORKING, 1.0), (WORKING, 0.25), (WORKING, -1.0), (FREE, -1.0)],
        True,
        0.25,
    ),
    "never a valid distance": ([(WORKING, -1.0), (FREE, -1.0)], False, None),
    "free at -1 far away": ([(WORKING, 2.0), (FREE, -1.0)], False, 2.0),
    "free at its own distance": ([(WORKING, 0.1), (FREE, 2.5)], False, 2.5),
}


def scripted_goal(steps: list[tuple[int, float]]) -> Any:
    async def script(fake: ScriptedRobot, command: Goto) -> None:
        await fake.frames(REACTION_FRAMES)
        for target_status, distance in steps:
            fake.set(
                target_num_id=command.target_id,
                target_status=target_status,
                target_distance=distance,
            )
            await fake.frames(3)

    return script


async def goto_outcome(robot: galileo_async.Robot) -> tuple[bool, float | None]:
    try:
        result = await robot.goto(3, timeout=5)
    except GoalAborted as exc:
        return False, exc.distance
    assert isinstance(result, GoalResult)
    return True, result.distance


async def event_outcome(events: Any) -> tuple[bool, float | None]:
    async for event in events:
        if isinstance(event, (ev.GoalReached, ev.GoalAbortedEvent)) and event.target_id == 3:
            return isinstance(event, ev.GoalReached), event.distance
    raise AssertionError("events() ended without the goal's end")


@pytest.mark.parametrize("case", list(ENDS))
async def test_goto_and_events_report_the_same_end(case: str) -> None:
    steps, reached, distance = ENDS[case]
    fake = ScriptedRobot()
    fake.scripts[Goto] = scripted_goal(steps)
    async with connected(fake) as (robot, _):
        events = robot.events()  # subscribed before the goal is sent
        try:
            with anyio.fail_after(5):
                by_goto = await goto_outcome(robot)
                by_events = await event_outcome(events)
        finally:
            await events.aclose()
    assert by_goto == by_events == (reached, distance)


async def test_a_goal_sent_again_forgets_the_distance_of_its_previous_run() -> None:
    # Goal 3 runs twice: the first run ends at 0.25 m; the second never shows a valid
    # distance and ends free far away. The second end must not borrow the first's 0.25 m.
    runs = iter([[(WORKING, 0.25), (FREE, -1.0)], [(WORKING, -1.0), (FREE, -1.0)]])

    async def script(fake: ScriptedRobot, command: Goto) -> None:
        await scripted_goal(next(runs))(fake, command)

    fake = ScriptedRobot()
    fake.scripts[Goto] = script
    async with connected(fake) as (robot, _):
        events = robot.events()
        try:
            with anyio.fail_after(5):
                first = (await goto_outcome(robot), await event_outcome(events))
                second = (await goto_outcome(robot), await event_outcome(events))
        finally:
            await events.aclose()
    assert first == ((True, 0.25), (True, 0.25))
    assert second == ((False, None), (False, None))


def test_the_store_forgets_a_finished_run_when_the_goal_starts_again() -> None:
    store = StatusStore()
    seen: list[Event] = []
    store.add_event_listener(seen.append)
    running = st(target_num_id=3, target_status=WORKING, target_distance=0.1)
    blind = running.model_copy(update={"target_distance": -1.0})
    free = running.model_copy(update={"target_status": FREE, "target_distance": -1.0})
    for status in (free, running, blind, free, blind, blind, free):
        store.update(status)
    ends = [e for e in seen if isinstance(e, (ev.GoalReached, ev.GoalAbortedEvent))]
    assert [(type(e), e.distance) for e in ends] == [
        (ev.GoalReached, 0.1),
        (ev.GoalAbortedEvent, None),
    ]


# --- the rule itself (pure) ------------------------------------------------------------


def st(**fields: Any) -> GalileoStatus:
    return GalileoStatus(**fields)


def test_valid_distance_and_end_distance() -> None:
    assert [valid_distance(d) for d in (None, -1.0, -0.5, 0.0, 2.0)] == [None, None, None, 0.0, 2.0]
    assert end_distance(st(target_distance=-1.0), 0.2) == 0.2
    assert end_distance(st(target_distance=0.5), 0.2) == 0.5
    assert end_distance(st(), None) is None


def test_arrived_needs_a_known_distance_within_tolerance() -> None:
    assert arrived(0.0, 0.3)
    assert arrived(0.3, 0.3)
    assert not arrived(0.31, 0.3)
    assert not arrived(None, 0.3)


def test_a_watchers_goal_step_ends_with_the_last_valid_distance() -> None:
    working = st(target_num_id=3, target_status=WORKING, target_distance=-1.0)
    free = st(target_num_id=3, target_status=FREE, target_distance=-1.0)
    assert goal_step(working, free, last_distance=0.1)[:2] == (((GoalChange.REACHED, 3),), 0.1)
    assert goal_step(working, free)[:2] == (((GoalChange.ABORTED, 3),), None)
    near = working.model_copy(update={"target_distance": 0.05})
    assert goal_step(near, free, last_distance=3.0)[:2] == (((GoalChange.REACHED, 3),), 0.05)


def test_a_watchers_goal_step_cancel_and_preempt() -> None:
    working = st(target_num_id=3, target_status=WORKING)
    assert goal_step(working, st(target_num_id=-1, target_status=FREE)).changes == (
        (GoalChange.CANCELLED, 3),
    )
    assert goal_step(working, st(target_num_id=4, target_status=WORKING)).changes == (
        (GoalChange.PREEMPTED, 3),
        (GoalChange.ACCEPTED, 4),
    )
    assert goal_step(working, st(target_num_id=3)).changes == ()


def test_running_distance_counts_only_the_running_goal() -> None:
    prev = st(target_num_id=3, target_status=WORKING, target_distance=-1.0)
    measured = st(target_num_id=3, target_status=WORKING, target_distance=0.4)
    assert running_distance(measured, prev) == 0.4
    assert running_distance(None, prev) is None
    other_goal = measured.model_copy(update={"target_num_id": 4})
    assert running_distance(other_goal, prev) is None
    not_running = measured.model_copy(update={"target_status": FREE})
    assert running_distance(not_running, prev) is None


def test_derive_events_uses_the_rule() -> None:
    prev = st(target_num_id=3, target_status=WORKING, target_distance=0.0)
    cur = st(target_num_id=3, target_status=FREE, target_distance=-1.0)
    (event,) = derive_events(prev, cur)
    assert isinstance(event, ev.GoalReached)
    assert event.distance == 0.0


# --- events' own names -------------------------------------------------------------------

SHARED_NAMES = ("GoalAborted", "GoalCancelled", "LinkStale", "ConnectionLost")


@pytest.mark.parametrize("name", SHARED_NAMES)
def test_an_event_named_as_an_error_is_another_class_with_event_in_its_name(name: str) -> None:
    event = getattr(ev, f"{name}Event")
    assert not hasattr(ev, name)
    assert name not in ev.__all__
    assert f"{name}Event" in ev.__all__
    # The error keeps its name; the event is another class.
    error = getattr(galileo_async, name)
    assert issubclass(error, Exception)
    assert error is not event
    assert not issubclass(event, Exception)
    assert event.name == name  # what str(), the CLI and VDA 5050 show


def test_unknown_names_still_raise_attribute_error() -> None:
    with pytest.raises(AttributeError, match="NoSuchEvent"):
        ev.NoSuchEvent  # noqa: B018


def test_every_event_has_a_name() -> None:
    assert Event.name == "Event"
    assert ev.GoalReached.name == "GoalReached"
    assert ev.ConnectionLostEvent(status=None, reason="x").name == "ConnectionLost"
