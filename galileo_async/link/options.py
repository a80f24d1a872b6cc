"""A link's tunable options: their defaults and the checks they pass before anything opens."""

from __future__ import annotations

from ..errors import InvalidArgument

__all__ = [
    "CLOSE_TIMEOUT",
    "DEFAULT_DRAIN_TIMEOUT",
    "DEFAULT_MAX_QUEUED_COMMANDS",
    "DEFAULT_MIN_COMMAND_INTERVAL",
    "DEFAULT_RECONNECT_INITIAL",
    "DEFAULT_RECONNECT_MAX",
    "DEFAULT_STALE_RECONNECT",
    "DEFAULT_STALE_TIMEOUT",
    "DRAIN_POLL_INTERVAL",
    "check_options",
]

#: The document allows at most 100 commands/s; back-to-back writes lose commands (PROTOCOL.md §2).
DEFAULT_MIN_COMMAND_INTERVAL = 0.010
#: Status arrives at 30 Hz; this long without a valid frame makes the link stale.
DEFAULT_STALE_TIMEOUT = 1.0
#: Silent for this many stale_timeouts: the peer is taken for dead and the link reconnects.
DEFAULT_STALE_RECONNECT = 5.0
#: Longest the transport may hold unsent bytes before the queued sends fail.
DEFAULT_DRAIN_TIMEOUT = 2.0
#: How often a writer waiting for the transport's buffer to empty looks again.
DRAIN_POLL_INTERVAL = 0.005
#: Commands waiting for the writer (one second at the 100/s maximum); send() waits when full.
DEFAULT_MAX_QUEUED_COMMANDS = 100
DEFAULT_RECONNECT_INITIAL = 0.1
DEFAULT_RECONNECT_MAX = 5.0
#: Longest close() waits for its tasks and for the transport to close.
CLOSE_TIMEOUT = 2.0


def check_options(
    *,
    reconnect_initial: float,
    reconnect_max: float,
    stale_timeout: float | None,
    stale_reconnect: float | None,
    min_command_interval: float,
    drain_timeout: float,
    max_queued_commands: int,
) -> None:
    """Raise InvalidArgument for the first option a link cannot work with."""
    if not 0 < reconnect_initial <= reconnect_max:
        raise InvalidArgument("need 0 < reconnect_initial <= reconnect_max")
    if stale_timeout is not None and stale_timeout <= 0:
        raise InvalidArgument(f"stale_timeout must be positive or None, got {stale_timeout}")
    if stale_reconnect is not None and not stale_reconnect >= 1:
        raise InvalidArgument(
            f"stale_reconnect must be >= 1 (times stale_timeout) or None, got {stale_reconnect}"
        )
    if min_command_interval < 0:
        raise InvalidArgument(f"min_command_interval must be >= 0, got {min_command_interval}")
    if not drain_timeout > 0:
        raise InvalidArgument(f"drain_timeout must be positive, got {drain_timeout}")
    queued = max_queued_commands
    if isinstance(queued, bool) or not (isinstance(queued, int) and queued >= 1):
        raise InvalidArgument(f"max_queued_commands must be an int >= 1, got {queued!r}")
