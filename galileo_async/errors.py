"""Every exception the driver raises, grouped by category under one root."""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from .models import GalileoStatus

__all__ = [
    "AcceptTimeout",
    "AsyncioRequired",
    "AuthenticationError",
    "CommandSuperseded",
    "ConnectionLost",
    "DuplicateVehicle",
    "GalileoConnectionError",
    "GalileoError",
    "GalileoTimeout",
    "GoalAborted",
    "GoalCancelled",
    "GoalError",
    "GoalRejected",
    "GoalStalled",
    "HttpError",
    "HttpTimeout",
    "InvalidArgument",
    "LinkStale",
    "NotReady",
    "NotSupported",
    "OperationFailed",
    "OperationTimeout",
    "PortBusy",
    "StopUnconfirmed",
    "UnconfirmedOperation",
    "WrongEventLoop",
]


class GalileoError(Exception):
    """Root of every error raised by galileo_async."""


# --- bad input -------------------------------------------------------------


class InvalidArgument(GalileoError, ValueError):
    """An argument is out of range or of the wrong kind; nothing was sent."""


# --- runtime -----------------------------------------------------------------


class AsyncioRequired(GalileoError, RuntimeError):
    """Called where no asyncio event loop runs (e.g. under trio): the driver runs on asyncio."""


class WrongEventLoop(GalileoError, RuntimeError):
    """A Robot was called from another event loop or thread than the one that connected it."""


class DuplicateVehicle(GalileoError):
    """Another VDA 5050 vehicle with this manufacturer and serial number holds the broker."""


# --- link --------------------------------------------------------------------


class GalileoConnectionError(GalileoError, ConnectionError):
    """The link to the robot cannot be opened or is gone."""


class ConnectionLost(GalileoConnectionError):
    """The transport dropped while an operation was waiting on it."""


class PortBusy(GalileoConnectionError):
    """The serial port ``port`` is open elsewhere (serial ports are opened exclusively)."""

    def __init__(self, message: str, *, port: str) -> None:
        super().__init__(message)
        self.port = port


class LinkStale(GalileoConnectionError):
    """No valid status frame arrived for longer than the stale timeout."""

    def __init__(self, message: str, *, silent_for: float) -> None:
        super().__init__(message)
        self.silent_for = silent_for


# --- state -------------------------------------------------------------------


class NotReady(GalileoError):
    """A precondition does not hold in the latest status; nothing was sent."""

    def __init__(self, message: str, status: GalileoStatus | None) -> None:
        super().__init__(message)
        self.status = status


class CommandSuperseded(GalileoError):
    """A user stop (``superseded_by``, e.g. "stop()") came while the command waited; not sent."""

    def __init__(self, message: str, *, superseded_by: str) -> None:
        super().__init__(message)
        self.superseded_by = superseded_by


class OperationFailed(GalileoError):
    """The status showed that an operation failed (e.g. a charging or rotation error)."""

    def __init__(self, message: str, status: GalileoStatus | None) -> None:
        super().__init__(message)
        self.status = status


class GalileoTimeout(GalileoError, TimeoutError):
    """A wait ran past its deadline."""

    def __init__(self, message: str, status: GalileoStatus | None = None) -> None:
        super().__init__(message)
        self.status = status


class OperationTimeout(GalileoTimeout):
    """An operation did not reach its end state in time."""


class UnconfirmedOperation(GalileoTimeout):
    """A command was sent but the status never showed its effect in time."""


class StopUnconfirmed(UnconfirmedOperation):
    """stop() sent everything, but the status did not show ``unconfirmed`` in time.

    ``unconfirmed`` names each part the robot did not confirm: "goal" (still working or
    paused), "patrol" (loop_status still 1), "docking" (still finding or docking onto the
    charger), "speed" (still moving).
    """

    def __init__(
        self, message: str, status: GalileoStatus | None, *, unconfirmed: tuple[str, ...]
    ) -> None:
        super().__init__(message, status)
        self.unconfirmed = unconfirmed


# --- goals -------------------------------------------------------------------


class GoalError(GalileoError):
    """A goal ended without arriving."""

    def __init__(
        self, message: str, *, target_id: int, status: GalileoStatus | None = None
    ) -> None:
        super().__init__(message)
        self.target_id = target_id
        self.status = status


class AcceptTimeout(GoalError, GalileoTimeout):
    """The robot never showed the goal as accepted within accept_timeout."""


class GoalRejected(GoalError):
    """The robot reported an error for the goal (an invalid or unreachable id)."""


class GoalAborted(GoalError):
    """The goal ended free but far from the target: the planner gave up."""

    def __init__(
        self,
        message: str,
        *,
        target_id: int,
        distance: float | None,
        status: GalileoStatus | None = None,
    ) -> None:
        super().__init__(message, target_id=target_id, status=status)
        self.distance = distance


class GoalCancelled(GoalError):
    """The goal was cancelled, or preempted by a newer goal (``preempted`` is True).

    ``cancelled_by`` names this Robot's call that ended it ("stop()", "close()" …); None
    when the robot showed the cancel (another host, cancel()) or a newer goal preempted it.
    """

    def __init__(
        self,
        message: str,
        *,
        target_id: int,
        preempted: bool = False,
        status: GalileoStatus | None = None,
        cancelled_by: str | None = None,
    ) -> None:
        super().__init__(message, target_id=target_id, status=status)
        self.preempted = preempted
        self.cancelled_by = cancelled_by


class GoalStalled(GoalError):
    """The goal made no progress for ``stalled_for`` s of unpaused time (progress_timeout)."""

    def __init__(
        self,
        message: str,
        *,
        target_id: int,
        stalled_for: float,
        status: GalileoStatus | None = None,
    ) -> None:
        super().__init__(message, target_id=target_id, status=status)
        self.stalled_for = stalled_for


# --- channels ------------------------------------------------------------------------


class NotSupported(GalileoError):
    """The operation exists only on another channel (e.g. maps over http://)."""


class HttpError(GalileoConnectionError):
    """An HTTP API call failed: ``endpoint`` and ``status`` (None: no answer) name it."""

    def __init__(self, message: str, *, endpoint: str, status: int | None) -> None:
        super().__init__(message)
        self.endpoint = endpoint
        self.status = status


class AuthenticationError(HttpError):
    """The robot refused the login (username, password) or the token; ``status`` 401 or None."""


# .status is None: neither an HTTP status (HttpError's) nor a GalileoStatus (GalileoTimeout's).
class HttpTimeout(HttpError, GalileoTimeout):  # type: ignore[misc]
    """An HTTP API call or the WebSocket's opening got no answer in time; ``status`` is None."""

    def __init__(self, message: str, *, endpoint: str) -> None:
        super().__init__(message, endpoint=endpoint, status=None)
