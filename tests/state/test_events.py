"""derive_events: one test per event type, plus the unknown-field and first-status rules."""

from __future__ import annotations

from typing import Any

import pytest

from galileo_async import events as ev
from galileo_async.models import ChargeStatus, GalileoStatus, StatusLayout
from galileo_async.protocol import V2_DEFAULTS
from galileo_async.transitions import derive_events

IDLE: dict[str, Any] = {**V2_DEFAULTS, "nav_status": 1, "visual_status": 1, "target_status": 0}


def st(**fields: Any) -> GalileoStatus:
    return GalileoStatus(**{**IDLE, **fields})


def kinds(events: list[ev.Event]) -> list[type[ev.Event]]:
    return [type(e) for e in events]


def test_first_status_has_no_transition() -> None:
    assert derive_events(None, st(nav_status=1, target_status=1)) == []


def test_frames_differing_only_in_counter_speed_pose_give_nothing() -> None:
    a = st(time_stamp=1, current_speed_x=0.0, current_pose_x=1.0, power=12.0)
    b = st(time_stamp=2, current_speed_x=0.4, current_pose_x=1.1, power=12.1)
    assert derive_events(a, b) == []


@pytest.mark.parametrize(
    ("field", "on", "off"),
    [
        ("nav_status", ev.NavigationOpened, ev.NavigationClosed),
        ("busy_status", ev.BusyStarted, ev.BusyEnded),
        ("loop_status", ev.PatrolStarted, ev.PatrolStopped),
        ("map_status", ev.MappingStarted, ev.MappingStopped),
    ],
)
def test_two_state_fields(field: str, on: type[ev.Event], off: type[ev.Event]) -> None:
    zero, one = st(**{field: 0}), st(**{field: 1})
    assert kinds(derive_events(zero, one)) == [on]
    assert kinds(derive_events(one, zero)) == [off]
    assert derive_events(one, one) == []
    (event,) = derive_events(zero, one)
    assert event.status is one


@pytest.mark.parametrize("field", ["nav_status", "busy_status", "loop_status", "map_status"])
def test_unknown_field_is_no_change(field: str) -> None:
    # Older layouts lack fields: None → value is not a transition.
    assert derive_events(st(**{field: None}), st(**{field: 1})) == []
    assert derive_events(st(**{field: 1}), st(**{field: None})) == []


@pytest.mark.parametrize(
    ("old", "new", "expected"),
    [
        (0, 1, [ev.VisualInitialised]),
        (-1, 2, [ev.VisualInitialised]),
        (1, 2, [ev.VisualLost]),
        (1, 0, [ev.VisualLost]),
        (1, -1, [ev.VisualLost]),
        (2, -1, []),  # already reported lost
        (2, 1, [ev.VisualRecovered]),
        (-1, 0, []),
        (None, 1, []),
    ],
)
def test_visual(old: int | None, new: int, expected: list[type[ev.Event]]) -> None:
    assert kinds(derive_events(st(visual_status=old), st(visual_status=new))) == expected


def test_charge_state_changed_carries_old_and_new() -> None:
    (event,) = derive_events(st(charge_status=0), st(charge_status=3))
    assert isinstance(event, ev.ChargeStateChanged)
    assert (event.old, event.new) == (ChargeStatus.FREE, ChargeStatus.FINDING_DOCK)
    assert derive_events(st(charge_status=None), st(charge_status=1)) == []


def test_goal_accepted_from_free() -> None:
    (event,) = derive_events(
        st(target_num_id=-1, target_status=0), st(target_num_id=3, target_status=1)
    )
    assert isinstance(event, ev.GoalAccepted)
    assert event.target_id == 3


def test_goal_accepted_after_an_error_and_after_defaults() -> None:
    for before in (-1, 3):
        events = derive_events(
            st(target_num_id=2, target_status=before), st(target_num_id=2, target_status=1)
        )
        assert kinds(events) == [ev.GoalAccepted]


def test_goal_reached_within_tolerance() -> None:
    (event,) = derive_events(
        st(target_num_id=3, target_status=1, target_distance=0.5),
        st(target_num_id=3, target_status=0, target_distance=0.004),
    )
    assert isinstance(event, ev.GoalReached)
    assert (event.target_id, event.distance) == (3, pytest.approx(0.004))


def test_goal_aborted_far_from_target() -> None:
    prev = st(target_num_id=3, target_status=1, target_distance=4.0)
    cur = st(target_num_id=3, target_status=0, target_distance=2.5)
    (event,) = derive_events(prev, cur)
    assert isinstance(event, ev.GoalAbortedEvent)
    assert (event.target_id, event.distance) == (3, pytest.approx(2.5))
    assert kinds(derive_events(prev, cur, arrive_tolerance=3.0)) == [ev.GoalReached]


def test_goal_rejected_document_and_firmware_codes() -> None:
    # Document: error = 3. Firmware: -1 and target_num_id left unchanged (docs/protocol.md §2.b).
    for code in (3, -1):
        (event,) = derive_events(
            st(target_num_id=2, target_status=0), st(target_num_id=2, target_status=code)
        )
        assert isinstance(event, ev.GoalRejectedEvent)
        assert event.target_id == 2
    assert kinds(
        derive_events(st(target_num_id=3, target_status=1), st(target_num_id=3, target_status=3))
    ) == [ev.GoalRejectedEvent]


def test_repeated_error_is_not_a_new_failure() -> None:
    a = st(target_num_id=2, target_status=-1)
    assert derive_events(a, st(target_num_id=2, target_status=3)) == []


def test_goal_cancelled_when_id_drops_to_none() -> None:
    (event,) = derive_events(
        st(target_num_id=3, target_status=1), st(target_num_id=-1, target_status=0)
    )
    assert isinstance(event, ev.GoalCancelledEvent)
    assert (event.target_id, event.preempted) == (3, False)


def test_goal_preempted_by_a_new_goal() -> None:
    events = derive_events(
        st(target_num_id=3, target_status=2), st(target_num_id=5, target_status=1)
    )
    assert kinds(events) == [ev.GoalCancelledEvent, ev.GoalAccepted]
    cancelled, accepted = events
    assert isinstance(cancelled, ev.GoalCancelledEvent)
    assert isinstance(accepted, ev.GoalAccepted)
    assert (cancelled.target_id, cancelled.preempted, accepted.target_id) == (3, True, 5)


def test_pause_and_resume() -> None:
    working, paused = st(target_num_id=4, target_status=1), st(target_num_id=4, target_status=2)
    assert kinds(derive_events(working, paused)) == [ev.GoalPaused]
    assert kinds(derive_events(paused, working)) == [ev.GoalResumed]
    (event,) = derive_events(paused, working)
    assert isinstance(event, ev.GoalResumed)
    assert event.target_id == 4


def test_goal_seen_first_as_paused() -> None:
    events = derive_events(
        st(target_num_id=-1, target_status=0), st(target_num_id=4, target_status=2)
    )
    assert kinds(events) == [ev.GoalAccepted, ev.GoalPaused]


def test_unknown_goal_state_is_no_change() -> None:
    prev = st(target_num_id=3, target_status=None)
    assert derive_events(prev, st(target_num_id=3, target_status=1)) == []


def test_several_changes_in_one_frame() -> None:
    prev = st(nav_status=1, visual_status=1, loop_status=1, target_num_id=3, target_status=1)
    cur = st(nav_status=0, visual_status=-1, loop_status=0, target_num_id=-1, target_status=0)
    assert kinds(derive_events(prev, cur)) == [
        ev.NavigationClosed,
        ev.VisualLost,
        ev.GoalCancelledEvent,
        ev.PatrolStopped,
    ]


def test_older_layout_without_map_fields() -> None:
    prev = GalileoStatus(layout=StatusLayout.V1, nav_status=0, visual_status=0)
    cur = GalileoStatus(layout=StatusLayout.V1, nav_status=1, visual_status=1)
    assert kinds(derive_events(prev, cur)) == [ev.NavigationOpened, ev.VisualInitialised]


def test_events_are_frozen_and_typed() -> None:
    event = ev.LinkStaleEvent(status=None, silent_for=1.5)
    with pytest.raises(AttributeError):
        event.silent_for = 2.0  # type: ignore[misc]
    assert isinstance(event, ev.Event)
    assert isinstance(ev.GoalReached(status=None, target_id=1, distance=0.0), ev.GoalEvent)


def test_str_is_compact() -> None:
    event = ev.GoalCancelledEvent(status=st(), target_id=3, preempted=True)
    assert str(event) == "GoalCancelled(target_id=3, preempted=True)"
    assert str(ev.NavigationOpened(status=None)) == "NavigationOpened()"
