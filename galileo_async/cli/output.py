"""Where the command line writes: consoles on stdout and stderr, JSON lines, UTC times."""

from __future__ import annotations

import datetime
import json
import sys
from typing import Any, Protocol

from rich.console import Console

from .._checks import hide_secrets

__all__ = ["err_console", "out_console", "print_json", "timestamp"]


class _Invocation(Protocol):
    """What print_json needs of the invocation's Settings."""

    @property
    def port(self) -> str:
        """The port as given."""


def print_json(settings: _Invocation, data: dict[str, Any]) -> None:
    """Print one JSON object on stdout, naming the port it came from first (``"port"``).

    A password or token in the port's URL shows as ``***``.
    """
    out_console().print(json.dumps({"port": hide_secrets(settings.port)} | data), markup=False)


def out_console() -> Console:
    """A console on the current stdout (data and results)."""
    return Console(file=sys.stdout, highlight=False, soft_wrap=True)


def err_console() -> Console:
    """A console on the current stderr (progress, messages, errors)."""
    return Console(file=sys.stderr, highlight=False, soft_wrap=True)


def timestamp() -> str:
    """The wall-clock time now, ISO 8601 UTC with milliseconds (``2026-11-25T22:01:52.123Z``)."""
    now = datetime.datetime.now(datetime.timezone.utc)
    return now.isoformat(timespec="milliseconds").replace("+00:00", "Z")
