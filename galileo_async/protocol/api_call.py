"""ApiCall: one call of the robot's REST API as a command; http:// and https:// links only."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from ..errors import InvalidArgument
from .commands import Command

__all__ = ["ApiCall"]

_METHODS = ("GET", "POST", "PUT", "DELETE")


@dataclass(frozen=True, slots=True)
class ApiCall(Command):
    """``method`` on ``endpoint`` (below /api/v1) with query ``params`` and JSON ``body``.

    Sent through a link's send like any command, whose return value is the call's decoded
    JSON answer. The serial protocol has no such command: it has no payload.
    """

    method: str
    endpoint: str
    params: Mapping[str, Any] | None = field(default=None, hash=False)
    body: Mapping[str, Any] | None = field(default=None, hash=False)

    def __post_init__(self) -> None:
        if self.method not in _METHODS:
            raise InvalidArgument(
                f"method must be one of {', '.join(_METHODS)}, got {self.method!r}"
            )
        if not isinstance(self.endpoint, str) or not self.endpoint.startswith("/"):
            raise InvalidArgument(f"endpoint must be a path from '/', got {self.endpoint!r}")

    def payload(self) -> bytes:
        raise InvalidArgument("an ApiCall has no serial encoding (it needs an http:// link)")
