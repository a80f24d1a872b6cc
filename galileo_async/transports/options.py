"""A link's options: names, defaults and the checks they pass before anything opens."""

from __future__ import annotations

import functools
from collections.abc import Callable, Mapping
from typing import Any

from .._checks import check_bool, check_int, check_number, check_seconds, check_timeout
from ..errors import InvalidArgument
from ..protocol import LAYOUTS

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


#: Most commands a link may queue (far above any use: a bound, not a setting).
MAX_QUEUED_COMMANDS_LIMIT = 1_000_000
#: Highest baud rate taken: the operating system holds it in a C int.
MAX_BAUDRATE = 2**31 - 1
#: Options every link kind takes (BaseLink's).
LINK_OPTIONS = (
    "reconnect", "reconnect_initial", "reconnect_max", "stale_timeout", "stale_reconnect",
    "min_command_interval", "drain_timeout", "max_queued_commands",
)  # fmt: skip
#: Options a link kind ignores when they do not apply to it, so one set serves a fleet of
#: mixed URLs (a serial port has no connect timeout, a socket no baud rate).
PORTABLE_OPTIONS = ("baudrate", "serial_options", "connect_timeout")
#: Options of the serial, socket:// and sim:// links on top of LINK_OPTIONS.
STREAM_OPTIONS = ("layout", *PORTABLE_OPTIONS)
#: Options of udp:// links on top of LINK_OPTIONS: the portable ones, ignored (the layout
#: is told by each frame's length byte).
UDP_OPTIONS = PORTABLE_OPTIONS


def _check_stale_reconnect(name: str, value: object) -> None:
    if value is not None:
        check_number(name, value, low=1.0)


def _check_queue(name: str, value: object) -> None:
    check_int(name, value, 1, MAX_QUEUED_COMMANDS_LIMIT)


#: The status layouts a byte stream can carry (``"ros"`` and ``"udp_*"`` are other links' own).
STREAM_LAYOUTS = tuple(layout.value for layout in LAYOUTS)


def _check_layout(name: str, value: object) -> None:
    if value is not None and value not in STREAM_LAYOUTS:
        known = ", ".join(map(repr, STREAM_LAYOUTS))
        raise InvalidArgument(f"{name} must be None (detect it) or one of {known}, got {value!r}")


def _check_baudrate(name: str, value: object) -> None:
    check_int(name, value, 1, MAX_BAUDRATE)


def _check_serial_options(name: str, value: object) -> None:
    if value is None:
        return
    if not isinstance(value, Mapping) or not all(isinstance(key, str) for key in value):
        raise InvalidArgument(f"{name} must be a dict of pyserial settings, got {value!r}")


#: The check of each option of LINK_OPTIONS and STREAM_OPTIONS: (name, value) -> None or raise.
OPTION_CHECKS: dict[str, Callable[[str, Any], object]] = {
    "reconnect": check_bool,
    "reconnect_initial": check_seconds,
    "reconnect_max": check_seconds,
    "stale_timeout": check_timeout,
    "stale_reconnect": _check_stale_reconnect,
    "min_command_interval": functools.partial(check_seconds, allow_zero=True),
    "drain_timeout": check_seconds,
    "max_queued_commands": _check_queue,
    "layout": _check_layout,
    "baudrate": _check_baudrate,
    "serial_options": _check_serial_options,
    "connect_timeout": check_seconds,
}


def check_values(options: Mapping[str, Any]) -> None:
    """Raise InvalidArgument, naming the option, for the first value OPTION_CHECKS rejects."""
    for name, value in options.items():
        check = OPTION_CHECKS.get(name)
        if check is not None:
            check(name, value)
    initial = options.get("reconnect_initial", DEFAULT_RECONNECT_INITIAL)
    maximum = options.get("reconnect_max", DEFAULT_RECONNECT_MAX)
    if initial > maximum:
        raise InvalidArgument(
            f"reconnect_initial ({initial}) must not exceed reconnect_max ({maximum})"
        )


def check_options(
    *,
    reconnect: bool = True,
    reconnect_initial: float,
    reconnect_max: float,
    stale_timeout: float | None,
    stale_reconnect: float | None,
    min_command_interval: float,
    drain_timeout: float,
    max_queued_commands: int,
) -> None:
    """Raise InvalidArgument for the first option a link cannot work with."""
    check_values(
        {
            "reconnect": reconnect,
            "reconnect_initial": reconnect_initial,
            "reconnect_max": reconnect_max,
            "stale_timeout": stale_timeout,
            "stale_reconnect": stale_reconnect,
            "min_command_interval": min_command_interval,
            "drain_timeout": drain_timeout,
            "max_queued_commands": max_queued_commands,
        }
    )
