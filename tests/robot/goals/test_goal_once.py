"""One goal ends once, and a target_status the protocol does not name tells nothing.

The frames go to a StatusStore's events() (a watcher, or told what this process sent) and to
GoalTracker (goto's follower); both follow transitions.GoalMachine.
"""

from __future__ import annotations

from typing import Any

import pytest

from galileo_async import GalileoStatus, GoalAborted, GoalCancelled
from galileo_async import events as ev
from galileo_async.events import Event
from galileo_async.robot.tracker import GoalTracker
from galileo_async.state import StatusStore
from galileo_async.transitions import SentGoal
from tests.robot.goals.test_goal_machine import frame as goal_frame

TOLERANCE = 0.3
ENDS = ("GoalReached", "GoalAborted", "GoalRejected", "GoalCancelled")


def status(nav: int = 1, target_id: int = 3, state: int = 1, distance: float = 2.0) -> Any:
    return goal_frame(nav, target_id, state, distance)


def goal_events(
    frames: list[GalileoStatus], *, send: int | None = None
) -> list[tuple[str, int | None]]:
    """The goal events of events() over ``frames`` (after the first); ``send``: g N before."""
    store = StatusStore(arrive_tolerance=TOLERANCE)
    seen: list[Event] = []
    store.add_event_listener(seen.append)
    store.update(frames[0])
    if send is not None:
        store.track_goal(SentGoal.written(send, frames[0]))
    for frame in frames[1:]:
        store.update(frame)
    return [(e.name, e.target_id) for e in seen if isinstance(e, ev.GoalEvent)]


def ends_of(events: list[tuple[str, int | None]], target_id: int) -> list[str]:
    return [name for name, tid in events if tid == target_id and name in ENDS]


# --- navigation closes under a goal still shown working, then the goal is freed ---------

#: What the robot shows after navigation closed under goal 3 (still shown working).
AFTER_CLOSE = {
    "freed in place, far away": status(nav=0, state=0, distance=2.0),
    "freed in place, at the target": status(nav=0, state=0, distance=0.0),
    "freed, id -1": status(nav=0, target_id=-1, state=0, distance=-1.0),
    "an error": status(nav=0, state=-1),
    "the document's error": status(nav=0, state=3),
}


@pytest.mark.parametrize("case", list(AFTER_CLOSE))
def test_a_watcher_sees_a_goal_that_navigation_closed_under_end_once(case: str) -> None:
    frames = [status(), status(nav=0), AFTER_CLOSE[case], AFTER_CLOSE[case]]
    assert ends_of(goal_events(frames), 3) == ["GoalCancelled"]


@pytest.mark.parametrize("case", list(AFTER_CLOSE))
def test_a_goal_this_host_sent_ends_once_when_navigation_closes_under_it(case: str) -> None:
    before = status(target_id=-1, state=0, distance=-1.0)
    frames = [before, status(), status(nav=0), AFTER_CLOSE[case]]
    events = goal_events(frames, send=3)
    assert (events[0], ends_of(events, 3)) == (("GoalAccepted", 3), ["GoalCancelled"])


def test_a_goal_shown_working_again_when_navigation_reopens_is_a_new_run() -> None:
    frames = [status(), status(nav=0), status(), status(state=0, distance=0.0)]
    assert goal_events(frames) == [
        ("GoalCancelled", 3),
        ("GoalAccepted", 3),
        ("GoalReached", 3),
    ]


def test_an_error_shown_when_navigation_reopens_is_a_new_goal_rejected() -> None:
    # A g 3 rejected as -1 leaves the id alone (docs/protocol.md §2.b): a new goal, refused.
    frames = [status(), status(nav=0), status(nav=0, state=0), status(state=-1)]
    assert ends_of(goal_events(frames), 3) == ["GoalCancelled", "GoalRejected"]


def test_goto_ends_where_events_end_a_goal_navigation_closed_under() -> None:
    before = status(target_id=-1, state=0, distance=-1.0)
    tracker = GoalTracker(3, before=before, arrive_tolerance=TOLERANCE)
    assert not tracker.feed(status())
    with pytest.raises(GoalCancelled, match="navigation"):
        tracker.feed(status(nav=0))


def test_goto_sent_under_a_goal_shown_working_with_navigation_closed_is_no_restart() -> None:
    # The goal shown is gone with the navigation (docs/protocol.md §2.a): g 3 is a new goal,
    # not a restart of a running one, so only a frame showing 3 working accepts it.
    before = status(nav=0)
    tracker = GoalTracker(3, before=before, arrive_tolerance=TOLERANCE)
    assert tracker.sent is not None
    assert tracker.sent.pending
    assert not tracker.accepted
    assert not tracker.feed(status())
    assert tracker.accepted


# --- a target_status the protocol does not name (newer firmware): no information ---------


@pytest.mark.parametrize("unknown", [4, 7, -5])
def test_a_watcher_compares_across_an_unknown_target_status(unknown: int) -> None:
    frames = [status(), status(state=unknown, distance=1.0), status(state=0, distance=0.0)]
    assert goal_events(frames) == [("GoalReached", 3)]


def test_an_unknown_target_status_is_neither_an_end_nor_a_change() -> None:
    frames = [
        status(),
        status(state=7),
        status(),
        status(state=2),
        status(state=7),
        status(state=2),
    ]
    assert goal_events(frames) == [("GoalPaused", 3)]


def test_a_goal_preempted_behind_an_unknown_target_status_is_seen() -> None:
    frames = [status(), status(state=4), status(target_id=5)]
    assert goal_events(frames) == [
        ("GoalCancelled", 3),
        ("GoalAccepted", 5),
    ]


def test_the_distance_of_an_unknown_target_status_is_not_the_goals() -> None:
    # Free at -1 (invalid): the end takes the last valid distance the goal showed running.
    frames = [status(distance=2.0), status(state=7, distance=0.1), status(state=0, distance=-1.0)]
    store = StatusStore(arrive_tolerance=TOLERANCE)
    seen: list[Event] = []
    store.add_event_listener(seen.append)
    for frame in frames:
        store.update(frame)
    aborted = [e for e in seen if isinstance(e, ev.GoalAbortedEvent)]
    assert [(e.target_id, e.distance) for e in aborted] == [(3, 2.0)]
    tracker = GoalTracker(3, before=status(target_id=-1, state=0), arrive_tolerance=TOLERANCE)
    assert not tracker.feed(frames[0])
    assert not tracker.feed(frames[1])
    with pytest.raises(GoalAborted) as caught:
        tracker.feed(frames[2])
    assert caught.value.distance == 2.0


def test_navigation_closing_with_an_unknown_target_status_ends_the_goal_once() -> None:
    frames = [status(), status(nav=0, state=7), status(nav=0, state=0), status(nav=0, state=7)]
    assert goal_events(frames) == [("GoalCancelled", 3)]
    tracker = GoalTracker(3, before=status(target_id=-1, state=0), arrive_tolerance=TOLERANCE)
    tracker.feed(frames[0])
    with pytest.raises(GoalCancelled):
        tracker.feed(frames[1])


def test_a_goal_this_host_sent_is_accepted_across_an_unknown_target_status() -> None:
    before = status(target_id=-1, state=0, distance=-1.0)
    frames = [before, status(target_id=3, state=4), status(), status(state=0, distance=0.1)]
    assert goal_events(frames, send=3) == [("GoalAccepted", 3), ("GoalReached", 3)]


def test_goto_sent_while_the_robot_shows_an_unknown_target_status_is_accepted() -> None:
    before = status(target_id=-1, state=7, distance=-1.0)
    tracker = GoalTracker(3, before=before, arrive_tolerance=TOLERANCE)
    assert not tracker.feed(status())
    assert tracker.accepted
    frames = [before, status(), status(state=0, distance=0.0)]
    assert goal_events(frames, send=3) == [("GoalAccepted", 3), ("GoalReached", 3)]
