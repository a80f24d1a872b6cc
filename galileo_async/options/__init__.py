"""Every option of connect(), described once: name, type, default, link kinds, doc, check.

``ConnectOptions`` is the one description: a TypedDict (``connect(url, **options)`` is typed
with it, so a misspelt option is a type error) whose fields carry an ``Option`` each.
``OPTIONS`` is read from it; connect(), the fleet file, the CLI and the docs' option table
are derived from ``OPTIONS``. A new link kind adds its name to ``LINK_KINDS`` and its own
options in description.py.
"""

from __future__ import annotations

import contextlib
from collections.abc import Collection, Iterator, Mapping
from contextvars import ContextVar
from typing import Any

from .._checks import check_names
from ..errors import InvalidArgument
from .checks import (
    DEFAULT_ACCEPT_TIMEOUT,
    DEFAULT_ANGLE_TOLERANCE,
    DEFAULT_BAUDRATE,
    DEFAULT_CONNECT_TIMEOUT,
    DEFAULT_DRAIN_TIMEOUT,
    DEFAULT_GOAL_TIMEOUT,
    DEFAULT_MASTER_CHECK_INTERVAL,
    DEFAULT_MAX_ANGULAR_SPEED,
    DEFAULT_MAX_LINEAR_SPEED,
    DEFAULT_MAX_QUEUED_COMMANDS,
    DEFAULT_MIN_COMMAND_INTERVAL,
    DEFAULT_PING_INTERVAL,
    DEFAULT_PROGRESS_TIMEOUT,
    DEFAULT_RECONNECT_INITIAL,
    DEFAULT_RECONNECT_MAX,
    DEFAULT_REQUEST_TIMEOUT,
    DEFAULT_RPC_TIMEOUT,
    DEFAULT_STALE_RECONNECT,
    DEFAULT_STALE_TIMEOUT,
    DEFAULT_WAIT_TIMEOUT,
    DEFAULT_WS_PORT,
    FIRST_STATUS_TIMEOUT,
    MAX_BAUDRATE,
    MAX_QUEUED_COMMANDS_LIMIT,
    MAX_TARGET_ID,
    STREAM_LAYOUTS,
)
from .description import LINK_KINDS, OPTIONS, OWNERS, ConnectOptions, Option, Owner

__all__ = [
    "DEFAULT_ACCEPT_TIMEOUT",
    "DEFAULT_ANGLE_TOLERANCE",
    "DEFAULT_BAUDRATE",
    "DEFAULT_CONNECT_TIMEOUT",
    "DEFAULT_DRAIN_TIMEOUT",
    "DEFAULT_GOAL_TIMEOUT",
    "DEFAULT_MASTER_CHECK_INTERVAL",
    "DEFAULT_MAX_ANGULAR_SPEED",
    "DEFAULT_MAX_LINEAR_SPEED",
    "DEFAULT_MAX_QUEUED_COMMANDS",
    "DEFAULT_MIN_COMMAND_INTERVAL",
    "DEFAULT_PING_INTERVAL",
    "DEFAULT_PROGRESS_TIMEOUT",
    "DEFAULT_RECONNECT_INITIAL",
    "DEFAULT_RECONNECT_MAX",
    "DEFAULT_REQUEST_TIMEOUT",
    "DEFAULT_RPC_TIMEOUT",
    "DEFAULT_STALE_RECONNECT",
    "DEFAULT_STALE_TIMEOUT",
    "DEFAULT_WAIT_TIMEOUT",
    "DEFAULT_WS_PORT",
    "FIRST_STATUS_TIMEOUT",
    "LINK_KINDS",
    "MAX_BAUDRATE",
    "MAX_QUEUED_COMMANDS_LIMIT",
    "MAX_TARGET_ID",
    "OPTIONS",
    "OWNERS",
    "STREAM_LAYOUTS",
    "ConnectOptions",
    "Option",
    "Owner",
    "check_options",
    "check_values",
    "names_for",
    "option_table",
    "options_checked",
]

_CHECKED: ContextVar[bool] = ContextVar("galileo_async_options_checked", default=False)


@contextlib.contextmanager
def options_checked() -> Iterator[None]:
    """Within: the options were checked already (connect() builds its link and Robot here)."""
    token = _CHECKED.set(True)
    try:
        yield
    finally:
        _CHECKED.reset(token)


def names_for(kind: str | None, owners: Collection[str] = OWNERS) -> frozenset[str]:
    """The options a link of ``kind`` takes from ``owners`` (kind None: any kind's)."""
    return frozenset(o.name for o in OPTIONS.values() if o.owner in owners and o.takes(kind))


def check_values(
    options: Mapping[str, Any], kind: str | None = None, *, skip: Collection[str] = ()
) -> None:
    """Raise InvalidArgument, naming the option, for the first value a ``kind`` link refuses.

    Names not described (or in ``skip``) are left alone; reconnect_initial must not
    exceed reconnect_max.
    """
    if _CHECKED.get():
        return
    for name, value in options.items():
        option = OPTIONS.get(name)
        if option is not None and name not in skip:
            option.check(value, kind)
    initial = options.get("reconnect_initial", DEFAULT_RECONNECT_INITIAL)
    maximum = options.get("reconnect_max", DEFAULT_RECONNECT_MAX)
    if "reconnect_initial" not in skip and initial > maximum:
        raise InvalidArgument(
            f"reconnect_initial ({initial}) must not exceed reconnect_max ({maximum})"
        )


def check_options(
    kind: str,
    options: Mapping[str, Any],
    *,
    owners: Collection[str] = ("link",),
    also: Collection[str] = (),
) -> None:
    """Raise InvalidArgument for an option a ``kind`` link does not take, or a bad value.

    ``owners``: whose options are taken; ``also``: further names taken and not checked.
    An unknown name gets a near miss; one of another link kind says where it applies.
    """
    if _CHECKED.get():
        return
    accepted = names_for(kind, owners) | set(also)
    for name in options:
        option = OPTIONS.get(name)
        if name not in accepted and option is not None and option.kinds is not None:
            if len(option.kinds) == 1:
                raise InvalidArgument(f"{name} applies to {next(iter(option.kinds))}:// links only")
            raise InvalidArgument(f"{name} does not apply to {kind}:// links")
    check_names(options, accepted)
    check_values(options, kind, skip=also)


def option_table() -> str:
    """The docs' option table (markdown), made from OPTIONS."""
    rows = ["| option | type | default | links | meaning |", "| --- | --- | --- | --- | --- |"]
    for option in OPTIONS.values():
        kinds = "all"
        if option.kinds is not None:
            taken = [k for k in LINK_KINDS if k in option.kinds]
            kinds = ", ".join(f"`{k}://`" if k != "serial" else "serial" for k in taken)
        type_name = getattr(option.type, "__name__", None) or str(option.type)
        type_name = type_name.replace("typing.", "").replace("collections.abc.", "")
        type_name = type_name.replace("|", "\\|")  # a table cell's pipe (GitHub markdown)
        rows.append(
            f"| `{option.name}` | `{type_name}` | {option.default!r} | {kinds} | {option.doc} |"
        )
    return "\n".join(rows) + "\n"
