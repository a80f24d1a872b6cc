"""What follows a written command: Sent, the Follower protocol, and Confirm, the usual one."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any, NamedTuple, Protocol, TypeVar

from ..errors import GalileoTimeout, OperationFailed, UnconfirmedOperation
from ..models import GalileoStatus
from .runtime import Deadline

if TYPE_CHECKING:
    from ..state.streams import Watch

__all__ = ["Confirm", "Follower", "Predicate", "Sent", "task_of"]

Predicate = Callable[[GalileoStatus], bool]
_R_co = TypeVar("_R_co", covariant=True)


class Sent(NamedTuple):
    """A command just written: the operation's name, its deadline, the latest status then.

    ``task``: the id of the HTTP API task the write started (a PoseGoal's), else None.
    """

    what: str
    deadline: Deadline
    status: GalileoStatus | None
    task: str | None = None


class Follower(Protocol[_R_co]):
    """What Operations.send does around the write of a command that has an effect."""

    def sending(self, before: GalileoStatus | None) -> None:
        """Called after every check, right before the write; may still refuse by raising."""

    async def follow(self, watch: Watch, sent: Sent) -> _R_co:
        """The command was written; ``watch`` holds every status since just before the write."""


class Confirm:
    """Follow a command until a later status shows ``done``; the Follower of most operations.

    UnconfirmedOperation when the status layout lacks ``field`` or the deadline passes
    (``hint`` says why the robot may not have shown it), OperationFailed once ``failed``
    holds for a later status. Returns that status.
    """

    __slots__ = ("done", "failed", "field", "hint")

    def __init__(
        self, done: Predicate, *, field: str, failed: Predicate | None = None, hint: str = ""
    ) -> None:
        self.done = done
        self.field = field
        self.failed = failed
        self.hint = hint

    def sending(self, before: GalileoStatus | None) -> None:
        """Nothing to prepare: only statuses after the write count."""

    async def follow(self, watch: Watch, sent: Sent) -> GalileoStatus:
        """The first status from the write on where ``done`` holds."""
        what, deadline, latest = sent.what, sent.deadline, sent.status
        if latest is not None and getattr(latest, self.field) is None:
            raise UnconfirmedOperation(
                f"{what}: sent, but the {latest.layout} status layout has no {self.field} "
                f"field, so the driver cannot confirm it{self.hint}",
                latest,
            )
        while True:
            try:
                status = await watch.next(deadline.remaining())
            except GalileoTimeout as exc:
                raise UnconfirmedOperation(
                    f"{what}: sent, but {self.field} did not show it within {deadline.timeout} s"
                    f"{self.hint}",
                    exc.status,
                ) from None
            if self.failed is not None and self.failed(status):
                raise OperationFailed(f"{what}: the robot reported a failure", status)
            if self.done(status):
                return status


def task_of(answer: Any) -> str | None:
    """The id of the HTTP API task a link's ``answer`` describes, if it is one."""
    task = answer.get("id") if isinstance(answer, dict) else None
    return task if isinstance(task, str) else None
