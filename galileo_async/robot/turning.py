"""Turning: Robot's rotate_to with a turn-in-place fallback, and turn_to (a mixin)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..errors import UnconfirmedOperation
from .operations import ROTATE_TIMEOUT
from .turn import turn_in_place

if TYPE_CHECKING:
    from .operations import Operations

__all__ = ["Turning"]


class Turning:
    """Robot's rotate_to with a fallback, and turn_to (a mixin before RobotServices)."""

    if TYPE_CHECKING:
        _ops: Operations

    async def rotate_to(
        self, degrees: float, *, timeout: float | None = ROTATE_TIMEOUT, fallback: bool = False
    ) -> None:
        """RobotServices.rotate_to; ``fallback``: when ``a`` is unconfirmed, turn_to() after."""
        try:
            await super().rotate_to(degrees, timeout=timeout)  # type: ignore[misc]
        except UnconfirmedOperation:
            if not fallback:
                raise
            await self.turn_to(degrees, timeout=timeout)

    async def turn_to(self, degrees: float, *, timeout: float | None = ROTATE_TIMEOUT) -> None:
        """Turn in place to ``degrees`` by drive() (every firmware), within angle_tolerance."""
        self._ops.ensure_loop()
        await turn_in_place(self, degrees, limit=timeout)  # type: ignore[arg-type]
