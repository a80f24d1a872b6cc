"""The stop on the way out of a mission, a schedule or an offloaded chain: one rule for all."""

from __future__ import annotations

import asyncio
import logging

from ..errors import GalileoError
from ..robot.runtime import finish_shielded
from .robot_api import MissionRobot

__all__ = ["EXIT_STOP_TIMEOUT", "exit_stop"]

_log = logging.getLogger(__name__)

#: Seconds the stop on the way out (cancellation, an error, the end of a schedule) may take.
EXIT_STOP_TIMEOUT = 5.0


async def exit_stop(robot: MissionRobot, what: str) -> None:
    """``robot.stop()`` within EXIT_STOP_TIMEOUT s, whatever cancels the caller meanwhile.

    A failed stop is logged (naming ``what``), never raised; a cancellation that arrives
    during the stop is raised once it is done (finish_shielded). A closed robot is left alone.
    """
    if robot.closed:
        return

    async def stop() -> None:
        try:
            await robot.stop(timeout=EXIT_STOP_TIMEOUT)
        except GalileoError as exc:
            _log.warning("%s failed: %s; the robot may still be moving", what, exc)

    await finish_shielded(asyncio.ensure_future(stop()), what)
