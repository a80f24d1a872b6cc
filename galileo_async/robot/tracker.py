"""GoalTracker: the statuses after ``g N`` in, a verdict out (no I/O)."""

from __future__ import annotations

from typing import NoReturn

from ..errors import GoalAborted, GoalCancelled, GoalRejected
from ..models import GalileoStatus, TargetStatus
from ..transitions import ACTIVE, arrived, end_distance, valid_distance

__all__ = ["ALREADY_THERE_FRAMES", "ALREADY_THERE_TIME", "GoalTracker"]

#: Frames in a row after ``g N`` that must show goal N free within arrive_tolerance, none
#: working, before the goal counts as done "already there" (GoalTracker.stood_there).
ALREADY_THERE_FRAMES = 10
#: Seconds after the write before "already there" may be decided (10 frames at 30 Hz):
#: frames that arrive in a burst may all predate the robot reading the command.
ALREADY_THERE_TIME = ALREADY_THERE_FRAMES / 30


def _failed_transition(previous: GalileoStatus | None, status: GalileoStatus) -> bool:
    """True when ``status`` shows a goal error that ``previous`` did not already show."""
    if previous is None or not status.goal_failed:
        return False
    if not previous.goal_failed:
        return True
    return (previous.target_num_id, previous.target_status) != (
        status.target_num_id,
        status.target_status,
    )


class GoalTracker:
    """Decide acceptance and the end of goal ``target_id`` from the statuses after the send.

    ``before`` is the latest status when the command was sent: the first frames after
    ``g N`` may still show it (a cached status re-sent with a new counter, PROTOCOL.md §1),
    so only transitions away from it count, never levels that it already showed.
    """

    def __init__(
        self, target_id: int, *, before: GalileoStatus | None, arrive_tolerance: float
    ) -> None:
        self.target_id = target_id
        self.arrive_tolerance = arrive_tolerance
        self.accepted = False
        self.distance: float | None = None
        #: The goal ended because the robot already stood at the target (no working frame).
        self.already_there = False
        self._there_frames = 0  # frames in a row at the target since the send, none working
        self._previous = before
        self._before_id = before.target_num_id if before is not None else None
        # Re-sending the goal that is already running: the firmware cancels and restarts it
        # (PROTOCOL.md §2.b), which may show one cancelled frame before it works again.
        self._restarting = (
            before is not None and before.target_num_id == target_id and before.goal_active
        )

    def feed(self, status: GalileoStatus) -> bool:
        """Consume one status; True when the goal arrived, GoalError when it ended otherwise."""
        try:
            if status.nav_status is not None and not status.navigating:
                raise GoalCancelled(
                    f"goal {self.target_id} ended: navigation was stopped",
                    target_id=self.target_id,
                    status=status,
                )
            if self.accepted:
                return self._track(status)
            return self._accept(status)
        finally:
            self._previous = status

    def _accept(self, status: GalileoStatus) -> bool:
        ours = status.target_num_id == self.target_id
        if ours and status.target_status == TargetStatus.WORKING:
            self.accepted = True
            self._note_distance(status)
            return False
        if _failed_transition(self._previous, status):
            # The document reports a bad goal as 3; the firmware as -1, leaving
            # target_num_id unchanged (PROTOCOL.md §2.b): an id check cannot be used.
            raise GoalRejected(
                f"the robot rejected goal {self.target_id} "
                f"(target_status {_name(status.target_status)}): no such target, "
                "or it cannot be reached",
                target_id=self.target_id,
                status=status,
            )
        if ours and self._before_id != self.target_id and status.target_status == TargetStatus.FREE:
            # Accepted and finished between two frames: the id changing to ours is the proof.
            self.accepted = True
            return self._track(status)
        if ours and self._near(status):
            self._there_frames += 1
        else:
            self._there_frames = 0
        return False

    def stood_there(self, status: GalileoStatus, since_send: float) -> bool:
        """Whether the goal is done because the robot stood at its target all along.

        Standing at target N already, the firmware may finish ``g N`` within one frame, so
        no frame ever shows it working and the id does not change: only the robot staying
        free at the target (ALREADY_THERE_FRAMES frames in a row up to ``status``, none
        working, and ALREADY_THERE_TIME seconds ``since_send``) tells it is done rather than
        not started.
        """
        if self.accepted or self._there_frames < ALREADY_THERE_FRAMES:
            return False
        if since_send < ALREADY_THERE_TIME:
            return False
        self.accepted = self.already_there = True
        self._note_distance(status)
        return True

    def _track(self, status: GalileoStatus) -> bool:
        state = status.target_status
        ours = status.target_num_id == self.target_id
        if self._restarting and not (ours and (status.goal_active or self._near(status))):
            # The first end seen is the restart's own cancel, not the end of the new goal;
            # free at the target is an arrival either way (the restart may show no cancel).
            self._restarting = False
            self.accepted = False
            return self._accept(status)
        if not ours:
            return self._id_changed(status)
        if state in ACTIVE:
            self._note_distance(status)
            return False
        if state == TargetStatus.FREE:
            self._note_distance(status)
            if arrived(self.distance, self.arrive_tolerance):
                return True
            where = (
                "at an unknown distance" if self.distance is None else (f"{self.distance:.2f} m")
            )
            raise GoalAborted(
                f"goal {self.target_id} stopped short, {where} from the target "
                f"(arrive_tolerance {self.arrive_tolerance} m): the planner gave up",
                target_id=self.target_id,
                distance=self.distance,
                status=status,
            )
        if status.goal_failed:
            raise GoalRejected(
                f"the robot reported an error for goal {self.target_id} while moving "
                f"(target_status {_name(state)})",
                target_id=self.target_id,
                status=status,
            )
        return False  # an unknown target_status value from newer firmware: not an end

    def _id_changed(self, status: GalileoStatus) -> NoReturn:
        preempted = status.goal_active
        what = f"preempted by goal {status.target_num_id}" if preempted else "cancelled"
        raise GoalCancelled(
            f"goal {self.target_id} was {what}",
            target_id=self.target_id,
            preempted=preempted,
            status=status,
        )

    def settle(self) -> None:
        """Stop treating the first end as a restart's cancel (the restart window is over)."""
        self._restarting = False

    def _near(self, status: GalileoStatus) -> bool:
        return status.target_status == TargetStatus.FREE and arrived(
            valid_distance(status.target_distance), self.arrive_tolerance
        )

    def _note_distance(self, status: GalileoStatus) -> None:
        self.distance = end_distance(status, self.distance)


def _name(value: TargetStatus | None) -> str:
    return "unknown" if value is None else f"{int(value)} ({value.name})"
