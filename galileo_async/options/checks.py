"""The defaults, bounds and value checks of the options (OPTIONS describes each)."""

from __future__ import annotations

import functools
import os
from collections.abc import Callable, Mapping
from typing import Any

from pydantic import SecretStr

from .._checks import check_int, check_number, check_seconds, check_timeout, parse_hosts
from ..errors import InvalidArgument
from ..models import StatusLayout
from ..protocol import LAYOUTS

DEFAULT_ACCEPT_TIMEOUT = 5.0
DEFAULT_GOAL_TIMEOUT = 600.0
DEFAULT_WAIT_TIMEOUT = 30.0
DEFAULT_PROGRESS_TIMEOUT = 60.0
DEFAULT_ANGLE_TOLERANCE = 2.0
#: m/s at 100 % of ``f``/``b`` (the vendor's MAX_VEL, docs/protocol.md §6.3).
DEFAULT_MAX_LINEAR_SPEED = 0.8
#: rad/s at 100 % of ``c``/``d`` (kinetic builds; noetic builds use 1.2).
DEFAULT_MAX_ANGULAR_SPEED = 1.5
FIRST_STATUS_TIMEOUT = 3.0
#: The document allows at most 100 commands/s; back-to-back writes lose commands
#: (docs/protocol.md §2).
DEFAULT_MIN_COMMAND_INTERVAL = 0.010
#: Status arrives at 30 Hz; this long without a valid frame makes the link stale.
DEFAULT_STALE_TIMEOUT = 1.0
#: Silent for this many stale_timeouts: the peer is taken for dead and the link reconnects.
DEFAULT_STALE_RECONNECT = 5.0
DEFAULT_DRAIN_TIMEOUT = 2.0
#: One second of commands at the 100/s maximum; send() waits when full.
DEFAULT_MAX_QUEUED_COMMANDS = 100
DEFAULT_RECONNECT_INITIAL = 0.1
DEFAULT_RECONNECT_MAX = 5.0
#: The navigation serial port runs at 115200 baud, 8N1 (docs/protocol.md, "Links and framing").
DEFAULT_BAUDRATE = 115200
DEFAULT_CONNECT_TIMEOUT = 5.0
DEFAULT_RPC_TIMEOUT = 2.0
#: The WebSocket port of the robot's HTTP API (its REST port is 3546).
DEFAULT_WS_PORT = 3547
#: Seconds between the WebSocket pings of the http:// link's own timer (http.md: about 1 s).
DEFAULT_PING_INTERVAL = 1.0
#: Seconds one REST call of the http:// link may take before it fails with HttpTimeout.
DEFAULT_REQUEST_TIMEOUT = 5.0
DEFAULT_MASTER_CHECK_INTERVAL = 1.0
#: Goal ids are one byte (docs/protocol.md §2.b).
MAX_TARGET_ID = 255
#: Most commands a link may queue (far above any use: a bound, not a setting).
MAX_QUEUED_COMMANDS_LIMIT = 1_000_000
#: Highest baud rate taken: the operating system holds it in a C int.
MAX_BAUDRATE = 2**31 - 1
#: The status layouts a byte stream can carry (``"ros"`` and ``"udp_*"`` are other links').
STREAM_LAYOUTS = tuple(layout.value for layout in LAYOUTS)

#: A value check: (name, value) -> None, or raise InvalidArgument naming the option.
Check = Callable[[str, Any], object]


def check_map_targets(name: str, value: object) -> None:
    if value is not None:
        check_int(name, value, 0, MAX_TARGET_ID)


def check_metres(name: str, value: object) -> None:
    check_number(name, value, low=0.0)


def check_degrees(name: str, value: object) -> None:
    check_number(name, value, low=0.0, high=180.0)


def check_speed_limit(name: str, value: object) -> None:
    # The vendor's node turns a percentage of these into a speed (docs/protocol.md §6.2, §6.3).
    check_number(name, value, low=0.0, low_open=True, high=10.0)


def check_stale_reconnect(name: str, value: object) -> None:
    if value is not None:
        check_number(name, value, low=1.0)


def check_queue(name: str, value: object) -> None:
    check_int(name, value, 1, MAX_QUEUED_COMMANDS_LIMIT)


def check_stream_layout(name: str, value: object) -> None:
    if value is not None and value not in STREAM_LAYOUTS:
        known = ", ".join(map(repr, STREAM_LAYOUTS))
        raise InvalidArgument(f"{name} must be None (detect it) or one of {known}, got {value!r}")


def check_ros_layout(name: str, value: object) -> None:
    if value is not None and str(value) != StatusLayout.ROS.value:
        raise InvalidArgument(
            f"{name} {value!r} does not apply to ros:// (status is decoded by name)"
        )


def check_baudrate(name: str, value: object) -> None:
    check_int(name, value, 1, MAX_BAUDRATE)


def check_serial_options(name: str, value: object) -> None:
    if value is None:
        return
    if not isinstance(value, Mapping) or not all(isinstance(key, str) for key in value):
        raise InvalidArgument(f"{name} must be a dict of pyserial settings, got {value!r}")


def check_secret(name: str, value: object) -> None:
    """A password or token: a non-empty string, a SecretStr or None; never shown in the error."""
    if value is None or isinstance(value, SecretStr):
        return
    if not isinstance(value, str) or not value:
        raise InvalidArgument(f"{name} must be a non-empty string or None")


def check_port(name: str, value: object) -> None:
    if isinstance(value, bool) or not isinstance(value, int) or not 0 < value < 65536:
        raise InvalidArgument(f"{name} must be a port number (1-65535), got {value!r}")


def check_http_layout(name: str, value: object) -> None:
    if value is not None and str(value) != StatusLayout.ROS.value:
        raise InvalidArgument(f"{name} {value!r} does not apply to http:// (JSON, by name)")


def check_name(name: str, value: object) -> None:
    if value is not None and not (isinstance(value, str) and value):
        raise InvalidArgument(f"{name} must be a non-empty string or None, got {value!r}")


def check_ca_file(name: str, value: object) -> None:
    """None, or the path (str or os.PathLike) of a readable file of PEM CA certificates."""
    if value is None:
        return
    if isinstance(value, bool) or not isinstance(value, (str, os.PathLike)) or not str(value):
        raise InvalidArgument(f"{name} must be the path of a PEM CA file or None, got {value!r}")
    if not os.path.isfile(value) or not os.access(value, os.R_OK):
        raise InvalidArgument(f"{name} {str(value)!r} is not a readable file")


def check_hosts(name: str, value: Any) -> None:
    if value is not None:
        parse_hosts(value)


seconds_or_zero = functools.partial(check_seconds, allow_zero=True)
timeout_not_none = functools.partial(check_timeout, allow_none=False)
