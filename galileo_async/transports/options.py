"""A link's options, as the one description (galileo_async.options) gives them."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

from .. import options as _options
from ..options import (
    DEFAULT_DRAIN_TIMEOUT,
    DEFAULT_MAX_QUEUED_COMMANDS,
    DEFAULT_MIN_COMMAND_INTERVAL,
    DEFAULT_RECONNECT_INITIAL,
    DEFAULT_RECONNECT_MAX,
    DEFAULT_STALE_RECONNECT,
    DEFAULT_STALE_TIMEOUT,
    MAX_BAUDRATE,
    MAX_QUEUED_COMMANDS_LIMIT,
    OPTIONS,
    STREAM_LAYOUTS,
)

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
    "LINK_OPTIONS",
    "MAX_BAUDRATE",
    "MAX_QUEUED_COMMANDS_LIMIT",
    "OPTION_CHECKS",
    "PORTABLE_OPTIONS",
    "STREAM_LAYOUTS",
    "STREAM_OPTIONS",
    "UDP_OPTIONS",
    "check_options",
    "check_values",
]

#: How often a writer waiting for the transport's buffer to empty looks again.
DRAIN_POLL_INTERVAL = 0.005
#: Longest close() waits for its tasks and for the transport to close.
CLOSE_TIMEOUT = 2.0


def _link_options(kind: str) -> tuple[str, ...]:
    """The link options a ``kind`` link takes on top of every link's (LINK_OPTIONS)."""
    return tuple(
        o.name for o in OPTIONS.values() if o.owner == "link" and o.kinds and kind in o.kinds
    )


#: Options a link kind ignores when they do not apply to it, so one set serves a fleet of
#: mixed URLs (a serial port has no connect timeout, a socket no baud rate).
PORTABLE_OPTIONS = ("baudrate", "serial_options", "connect_timeout")
#: Options every link kind takes (Link's).
LINK_OPTIONS = tuple(
    o.name
    for o in OPTIONS.values()
    if o.owner == "link" and o.kinds is None and o.name not in PORTABLE_OPTIONS
)
#: Options of the serial, socket:// and sim:// links on top of LINK_OPTIONS.
STREAM_OPTIONS = (*_link_options("socket"), *PORTABLE_OPTIONS)
#: Options of udp:// links on top of LINK_OPTIONS: the portable ones, ignored (the layout
#: is told by each frame's length byte).
UDP_OPTIONS = (*_link_options("udp"), *PORTABLE_OPTIONS)
#: The check of each link option: (name, value) -> None or raise.
OPTION_CHECKS: dict[str, Callable[[str, Any], object]] = {
    name: OPTIONS[name].check_value for name in (*LINK_OPTIONS, *STREAM_OPTIONS)
}


def check_values(options: Mapping[str, Any]) -> None:
    """Raise InvalidArgument, naming the option, for the first value a link refuses."""
    _options.check_values(options)


def check_options(**options: Any) -> None:
    """Raise InvalidArgument for the first option a link cannot work with (Link's)."""
    _options.check_values(options)
