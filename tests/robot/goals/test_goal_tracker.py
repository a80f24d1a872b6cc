"""The goto state machine alone: statuses in, verdicts out (no I/O)."""

from __future__ import annotations

from typing import Any

import pytest

from galileo_async import GalileoStatus, GoalAborted, GoalCancelled
from galileo_async.robot.goal import GoalTracker


def status(**fields: Any) -> GalileoStatus:
    return GalileoStatus(**({"nav_status": 1, "visual_status": 1} | fields))


def test_tracker_unknown_target_status_is_not_an_end() -> None:
    before = status(target_num_id=-1, target_status=0)
    tracker = GoalTracker(3, before=before, arrive_tolerance=0.3)
    assert not tracker.feed(status(target_num_id=3, target_status=1, target_distance=2.0))
    assert not tracker.feed(status(target_num_id=3, target_status=7, target_distance=1.0))
    assert tracker.feed(status(target_num_id=3, target_status=0, target_distance=0.0))


def test_tracker_invalid_final_distance_falls_back_to_the_last_known() -> None:
    tracker = GoalTracker(3, before=status(target_num_id=-1), arrive_tolerance=0.3)
    tracker.feed(status(target_num_id=3, target_status=1, target_distance=0.1))
    assert tracker.feed(status(target_num_id=3, target_status=0, target_distance=-1.0))
    assert tracker.distance == pytest.approx(0.1)


def test_tracker_free_at_an_unknown_distance_is_an_abort() -> None:
    tracker = GoalTracker(3, before=status(target_num_id=-1), arrive_tolerance=0.3)
    tracker.feed(status(target_num_id=3, target_status=1, target_distance=-1.0))
    with pytest.raises(GoalAborted) as caught:
        tracker.feed(status(target_num_id=3, target_status=0, target_distance=-1.0))
    assert caught.value.distance is None


def test_tracker_ignores_frames_before_acceptance() -> None:
    before = status(target_num_id=2, target_status=1, target_distance=4.0)
    tracker = GoalTracker(3, before=before, arrive_tolerance=0.3)
    for _ in range(3):  # stale: the previous goal still working
        assert not tracker.feed(before)
    assert not tracker.accepted
    tracker.feed(status(target_num_id=-1, target_status=0))  # firmware cancels the old goal
    assert not tracker.accepted
    tracker.feed(status(target_num_id=3, target_status=1, target_distance=1.0))
    assert tracker.accepted


def test_tracker_navigation_closing_before_acceptance_cancels() -> None:
    tracker = GoalTracker(3, before=status(target_num_id=-1), arrive_tolerance=0.3)
    tracker.feed(status(target_num_id=-1))  # stale
    with pytest.raises(GoalCancelled, match="navigation"):
        tracker.feed(status(nav_status=0, visual_status=-1, target_num_id=-1))


def test_tracker_restart_that_arrives_without_a_cancel_frame_is_an_arrival() -> None:
    # Re-sending the running goal: the firmware's restart may show no cancelled frame,
    # and a goal near its target then simply arrives.
    before = status(target_num_id=3, target_status=1, target_distance=0.6)
    tracker = GoalTracker(3, before=before, arrive_tolerance=0.3)
    assert not tracker.feed(status(target_num_id=3, target_status=1, target_distance=0.4))
    assert tracker.feed(status(target_num_id=3, target_status=0, target_distance=0.0))


def test_tracker_restart_cancel_frame_far_from_the_target_is_not_an_end() -> None:
    before = status(target_num_id=3, target_status=1, target_distance=5.0)
    tracker = GoalTracker(3, before=before, arrive_tolerance=0.3)
    tracker.feed(status(target_num_id=3, target_status=1, target_distance=5.0))  # stale
    assert not tracker.feed(status(target_num_id=3, target_status=0, target_distance=5.0))
    assert not tracker.feed(status(target_num_id=3, target_status=1, target_distance=4.9))
    assert tracker.feed(status(target_num_id=3, target_status=0, target_distance=0.0))
