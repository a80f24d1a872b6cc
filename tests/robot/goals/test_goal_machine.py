"""One goal state machine: goto's verdict and events()' first goal end agree on every sequence.

The same frames (and the same "what this process sent") go to GoalTracker, goto's follower,
and to a StatusStore's events(); both decide by transitions.goal_step. The goal is a map
target or a pose goal (goto_pose, goto_point over http://: target -2, which the machine
treats as no id when it only observes: an error under it is no rejection).
"""

from __future__ import annotations

from typing import Any

from hypothesis import given, settings
from hypothesis import strategies as st

from galileo_async import GalileoStatus, GoalAborted, GoalCancelled, GoalRejected
from galileo_async import events as ev
from galileo_async.events import Event
from galileo_async.robot.tracker import GoalTracker, cancelling
from galileo_async.state import StatusStore
from galileo_async.transitions import GoalChange, SentGoal, derive_events, goal_step

TARGET = 3
#: The id the robot shows for a goal by pose (an HTTP API nav task).
POSE = -2
TOLERANCE = 0.3

Verdict = tuple[int, str, Any] | None


def frame(nav: int, target_id: int, target_status: int, distance: float) -> GalileoStatus:
    return GalileoStatus(
        nav_status=nav,
        visual_status=1,
        power=24.0,
        target_num_id=target_id,
        target_status=target_status,
        target_distance=distance,
    )


ids = st.sampled_from([-1, POSE, 1, TARGET, 5])
#: The goal this process sends: a map target, or a pose goal.
targets = st.sampled_from([TARGET, POSE])
#: The protocol's values, and values newer firmware may add (the enum keeps them): they tell
#: nothing, so both sides must compare across them alike.
states = st.sampled_from([-1, 0, 1, 2, 3, 4, 7, -5])
distances = st.sampled_from([-1.0, 0.0, 0.2, 0.5, 2.0])
frames = st.builds(frame, st.sampled_from([0, 1, 1, 1]), ids, states, distances)
# goto refuses to send unless navigation is open: the status at the write shows it open.
befores = st.builds(frame, st.just(1), ids, states, distances)


def by_goto(
    before: GalileoStatus, sequence: list[GalileoStatus], cancel_at: int | None, target: int
) -> Verdict:
    """GoalTracker's verdict on goal ``target``: (frame index, end, detail), None: not ended."""
    tracker = GoalTracker(target, before=before, arrive_tolerance=TOLERANCE)
    for index, status in enumerate(sequence):
        if index == cancel_at and tracker.sent is not None:
            tracker.sent = cancelling(tracker.sent)
        try:
            if tracker.feed(status):
                return index, "reached", tracker.distance
        except GoalAborted as exc:
            return index, "aborted", exc.distance
        except GoalRejected:
            return index, "rejected", None
        except GoalCancelled as exc:
            return index, "cancelled", exc.preempted
    return None


def by_events(
    before: GalileoStatus, sequence: list[GalileoStatus], cancel_at: int | None, target: int
) -> Verdict:
    """The first end of goal ``target`` that events() reports, told what this process sent."""
    store = StatusStore(arrive_tolerance=TOLERANCE)
    seen: list[Event] = []
    store.add_event_listener(seen.append)
    store.update(before)
    origin = object()
    store.track_goal(SentGoal.written(target, before, origin))
    for index, status in enumerate(sequence):
        if index == cancel_at:
            store.revise_tracked_goal(origin, cancelling)
        store.update(status)
        for event in seen:
            if not isinstance(event, ev.GoalEvent) or event.target_id != target:
                continue
            if isinstance(event, ev.GoalReached):
                return index, "reached", event.distance
            if isinstance(event, ev.GoalAbortedEvent):
                return index, "aborted", event.distance
            if isinstance(event, ev.GoalRejectedEvent):
                return index, "rejected", None
            if isinstance(event, ev.GoalCancelledEvent):
                return index, "cancelled", event.preempted
        seen.clear()
    return None


@settings(max_examples=1500, deadline=None)
@given(
    before=befores,
    sequence=st.lists(frames, min_size=1, max_size=8),
    cancel_at=st.none() | st.integers(0, 7),
    target=targets,
)
def test_goto_and_events_agree_on_every_frame_sequence(
    before: GalileoStatus, sequence: list[GalileoStatus], cancel_at: int | None, target: int
) -> None:
    verdict = by_goto(before, sequence, cancel_at, target)
    assert verdict == by_events(before, sequence, cancel_at, target)


def test_a_pose_goal_is_followed_to_its_end_like_a_map_target() -> None:
    # The cases the generated sequences must reach for target -2 (so they cover it).
    before = frame(1, -1, 0, 0.0)
    working = frame(1, POSE, 1, 2.0)
    for end, verdict in (
        (frame(1, POSE, 0, 0.1), (1, "reached", 0.1)),
        (frame(1, POSE, 0, 2.0), (1, "aborted", 2.0)),
        (frame(0, POSE, 0, 2.0), (1, "cancelled", False)),
    ):
        sequence = [working, end]
        assert by_goto(before, sequence, None, POSE) == verdict
        assert by_events(before, sequence, None, POSE) == verdict
    refused = [frame(1, POSE, -1, -1.0)]
    assert by_goto(before, refused, None, POSE) == (0, "rejected", None)
    assert by_events(before, refused, None, POSE) == (0, "rejected", None)


#: The end of a goal that ran; a rejected goal (GoalRejected) never ran.
RUN_ENDS = (ev.GoalReached, ev.GoalAbortedEvent, ev.GoalCancelledEvent)


def ended_twice(
    before: GalileoStatus, sequence: list[GalileoStatus], send: bool, target: int = TARGET
) -> list[Any]:
    """Goal ids events() ends twice: a run's end after an end of that id with no GoalAccepted
    between (``send``: this process wrote goal ``target`` at ``before``)."""
    store = StatusStore(arrive_tolerance=TOLERANCE)
    seen: list[Event] = []
    store.add_event_listener(seen.append)
    store.update(before)
    if send:
        store.track_goal(SentGoal.written(target, before))
    for status in sequence:
        store.update(status)
    ended: set[int | None] = set()
    twice = []
    for event in seen:
        if not isinstance(event, ev.GoalEvent):
            continue
        if isinstance(event, ev.GoalAccepted):
            ended.discard(event.target_id)
        elif isinstance(event, (*RUN_ENDS, ev.GoalRejectedEvent)):
            if isinstance(event, RUN_ENDS) and event.target_id in ended:
                twice.append((event.name, event.target_id))
            ended.add(event.target_id)
    return twice


@settings(max_examples=1500, deadline=None)
@given(
    before=frames,
    sequence=st.lists(frames, min_size=1, max_size=8),
    send=st.booleans(),
    target=targets,
)
def test_events_end_each_goal_once(
    before: GalileoStatus, sequence: list[GalileoStatus], send: bool, target: int
) -> None:
    assert ended_twice(before, sequence, send, target) == []


@settings(max_examples=500, deadline=None)
@given(prev=frames, cur=frames)
def test_every_goal_end_is_one_event_of_the_same_name(
    prev: GalileoStatus, cur: GalileoStatus
) -> None:
    step = goal_step(prev, cur, arrive_tolerance=TOLERANCE)
    names = {
        GoalChange.REACHED: "GoalReached",
        GoalChange.ABORTED: "GoalAborted",
        GoalChange.REJECTED: "GoalRejected",
        GoalChange.CANCELLED: "GoalCancelled",
        GoalChange.PREEMPTED: "GoalCancelled",
        GoalChange.ACCEPTED: "GoalAccepted",
        GoalChange.PAUSED: "GoalPaused",
        GoalChange.RESUMED: "GoalResumed",
    }
    goal_events = [
        (e.name, e.target_id)
        for e in derive_events(prev, cur, arrive_tolerance=TOLERANCE)
        if isinstance(e, ev.GoalEvent)
    ]
    assert goal_events == [(names[change], target_id) for change, target_id in step.changes]
