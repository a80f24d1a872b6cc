"""connect()'s own options and the check of all of them before anything is opened."""

from __future__ import annotations

import functools
from collections.abc import Callable, Mapping
from typing import Any

from .._checks import check_int, check_number, check_timeout, naming
from ..transports import check_link_options
from .targets import MAX_TARGET_ID

__all__ = ["CONNECT_OPTIONS", "ROBOT_OPTIONS", "check_connect_options", "check_robot_options"]

#: Options connect() hands to the Robot.
ROBOT_OPTIONS = (
    "map_targets",
    "accept_timeout",
    "arrive_tolerance",
    "goal_timeout",
    "wait_timeout",
    "progress_timeout",
    "angle_tolerance",
    "max_linear_speed",
    "max_angular_speed",
)
#: Options connect() takes itself; the rest go to the link.
CONNECT_OPTIONS = (*ROBOT_OPTIONS, "first_status_timeout")


def _check_map_targets(name: str, value: object) -> None:
    if value is not None:
        check_int(name, value, 0, MAX_TARGET_ID)


def _check_metres(name: str, value: object) -> None:
    check_number(name, value, low=0.0)


def _check_degrees(name: str, value: object) -> None:
    check_number(name, value, low=0.0, high=180.0)


def _check_speed_limit(name: str, value: object) -> None:
    # The vendor's node turns a percentage of these into a speed (VENDOR.md §2.2, §2.3).
    check_number(name, value, low=0.0, low_open=True, high=10.0)


_CHECKS: dict[str, Callable[[str, Any], object]] = {
    "map_targets": _check_map_targets,
    "accept_timeout": functools.partial(check_timeout, allow_none=False),
    "arrive_tolerance": _check_metres,
    "goal_timeout": check_timeout,
    "wait_timeout": check_timeout,
    "progress_timeout": check_timeout,
    "angle_tolerance": _check_degrees,
    "first_status_timeout": check_timeout,
    "max_linear_speed": _check_speed_limit,
    "max_angular_speed": _check_speed_limit,
}


def check_robot_options(options: Mapping[str, Any]) -> None:
    """Raise InvalidArgument, naming the option, for the first bad value of CONNECT_OPTIONS."""
    for name, value in options.items():
        _CHECKS[name](name, value)


def check_connect_options(url: str, options: Mapping[str, Any]) -> None:
    """Raise InvalidArgument for a bad URL, an option its link does not take, or a bad value.

    Unknown names get a near-miss suggestion; nothing is opened or built.
    """
    own = {name: value for name, value in options.items() if name in CONNECT_OPTIONS}
    link = {name: value for name, value in options.items() if name not in CONNECT_OPTIONS}
    with naming(url, f"connect({url!r})"):
        check_link_options(url, link, also=CONNECT_OPTIONS)
        check_robot_options(own)
