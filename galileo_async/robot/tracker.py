"""GoalTracker: the statuses after ``g N`` in, a verdict out (no I/O), by a GoalMachine."""

from __future__ import annotations

from ..errors import GoalAborted, GoalCancelled, GoalError, GoalRejected
from ..models import GalileoStatus, TargetStatus
from ..transitions import ENDS, GoalChange, GoalMachine, SentGoal, at_target, end_distance

__all__ = ["ALREADY_THERE_FRAMES", "ALREADY_THERE_TIME", "GoalTracker"]

#: Frames in a row after ``g N`` that must show goal N free within arrive_tolerance, none
#: working, before the goal counts as done "already there" (GoalTracker.stood_there).
ALREADY_THERE_FRAMES = 10
#: Seconds after the write before "already there" may be decided (10 frames at 30 Hz):
#: frames that arrive in a burst may all predate the robot reading the command.
ALREADY_THERE_TIME = ALREADY_THERE_FRAMES / 30


class GoalTracker:
    """Decide acceptance and the end of goal ``target_id`` from the statuses after the send.

    ``before`` is the latest status when the command was sent: the first frames after
    ``g N`` may still show it (a cached status re-sent with a new counter, docs/protocol.md §1),
    so only transitions away from it count, never levels that it already showed. The
    verdicts are transitions.goal_step's, through a GoalMachine as the store's events().
    """

    def __init__(
        self,
        target_id: int,
        *,
        before: GalileoStatus | None,
        arrive_tolerance: float,
        origin: object = None,
    ) -> None:
        self.target_id = target_id
        self.arrive_tolerance = arrive_tolerance
        sent = SentGoal.written(target_id, before, origin)
        #: The goal rule with its memory, as the store's events() keeps one.
        self.machine = GoalMachine(sent=sent, arrive_tolerance=arrive_tolerance)
        self.machine.start(before)
        # A goal sent again while it runs is running from the write (SentGoal.restarting).
        self.accepted = not sent.pending
        self.distance: float | None = None
        #: The goal ended because the robot already stood at the target (no working frame).
        self.already_there = False
        self._there_frames = 0  # frames in a row at the target since the send, none working

    @property
    def sent(self) -> SentGoal | None:
        """The goal this process sent, as goal_step tracks it (None once the goal ended)."""
        return self.machine.sent

    @sent.setter
    def sent(self, sent: SentGoal | None) -> None:
        self.machine.sent = sent

    def feed(self, status: GalileoStatus) -> bool:
        """Consume one status; True when the goal arrived, GoalError when it ended otherwise."""
        step = self.machine.step(status)
        ours = status.target_num_id == self.target_id
        for change, target_id in step.changes:
            if target_id != self.target_id:
                continue
            if change is GoalChange.ACCEPTED:
                self.accepted = True
            elif change in ENDS:
                if change is GoalChange.REACHED:
                    self.distance = step.distance
                    return True
                if change is GoalChange.ABORTED:
                    self.distance = step.distance
                raise self._error(change, status)
        if self.sent is not None and self.sent.pending:
            self.accepted = False  # the restart's own cancel: the goal must show working again
            self._there_frames = self._there_frames + 1 if ours and self._near(status) else 0
        elif ours and self.accepted:
            self.distance = end_distance(status, self.distance)
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
        self.sent = None
        self.distance = end_distance(status, self.distance)
        return True

    def _near(self, status: GalileoStatus) -> bool:
        return at_target(status, self.arrive_tolerance)

    def _error(self, change: GoalChange, status: GalileoStatus) -> GoalError:
        target_id = self.target_id
        if change is GoalChange.REJECTED:
            state = _name(status.target_status)
            if self.accepted:
                message = f"the robot reported an error for goal {target_id} while moving"
                return GoalRejected(
                    f"{message} (target_status {state})", target_id=target_id, status=status
                )
            return GoalRejected(
                f"the robot rejected goal {target_id} (target_status {state}): no such target, "
                "or it cannot be reached",
                target_id=target_id,
                status=status,
            )
        if change is GoalChange.ABORTED:
            where = "at an unknown distance" if self.distance is None else f"{self.distance:.2f} m"
            return GoalAborted(
                f"goal {target_id} stopped short, {where} from the target "
                f"(arrive_tolerance {self.arrive_tolerance} m): the planner gave up",
                target_id=target_id,
                distance=self.distance,
                status=status,
            )
        preempted = change is GoalChange.PREEMPTED
        if status.nav_status is not None and not status.navigating:
            what = "ended: navigation was stopped"
        elif preempted:
            what = f"was preempted by goal {status.target_num_id}"
        else:
            what = "was cancelled"
        return GoalCancelled(
            f"goal {target_id} {what}", target_id=target_id, preempted=preempted, status=status
        )


def settled(sent: SentGoal) -> SentGoal:
    """``sent`` once its restart window is over: its first end is its own."""
    return sent._replace(restarting=False)


def cancelling(sent: SentGoal) -> SentGoal:
    """``sent`` once this process sent cancel (``i 2``) for it."""
    return sent._replace(cancelled=True)


def _name(value: TargetStatus | None) -> str:
    return "unknown" if value is None else f"{int(value)} ({value.name})"
