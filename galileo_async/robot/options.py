"""connect()'s own options and the check of all of them, once, before anything is opened."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from .._checks import naming
from ..links import check_link_options
from ..options import OPTIONS, OWNERS, check_values

__all__ = ["CONNECT_OPTIONS", "ROBOT_OPTIONS", "check_connect_options", "check_robot_options"]

#: Options connect() hands to the Robot.
ROBOT_OPTIONS = tuple(o.name for o in OPTIONS.values() if o.owner == "robot")
#: Options connect() takes itself; the rest go to the link.
CONNECT_OPTIONS = tuple(o.name for o in OPTIONS.values() if o.owner in ("robot", "connect"))


def check_robot_options(options: Mapping[str, Any]) -> None:
    """Raise InvalidArgument, naming the option, for the first bad value of CONNECT_OPTIONS."""
    check_values(options)


def check_connect_options(url: str, options: Mapping[str, Any]) -> None:
    """Raise InvalidArgument for a bad URL, an option its link does not take, or a bad value.

    Every option is checked once; unknown names get a near-miss suggestion; nothing is
    opened or built.
    """
    with naming(url, f"connect({url!r})"):
        check_link_options(url, options, owners=OWNERS)
