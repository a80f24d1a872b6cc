"""replayed_robot(): a Robot on a field recording (MCAP or ``galileo record``), replayed."""

from __future__ import annotations

import contextlib
import sys
from collections.abc import AsyncIterator
from pathlib import Path
from typing import TYPE_CHECKING

from ..errors import InvalidArgument
from ..models import GalileoStatus
from ..protocol import StatusDecoder
from ..robot import Robot
from ..sim.replay import load_capture
from .device import SimulatedDevice
from .robot import Clock, simulated_robot

if TYPE_CHECKING:
    from ..options import ConnectOptions

    if sys.version_info >= (3, 11):
        from typing import Unpack
    else:
        from typing_extensions import Unpack

__all__ = ["recorded_statuses", "replayed_robot"]


@contextlib.asynccontextmanager
async def replayed_robot(
    path: str | Path,
    *,
    robot: str | None = None,
    clock: Clock = "virtual",
    **options: Unpack[ConnectOptions],
) -> AsyncIterator[tuple[Robot, SimulatedDevice]]:
    """``async with replayed_robot("field.mcap") as (robot, device)``: a Robot on a recording.

    The link gets the recorded bytes at their recorded pace (on the virtual clock: as fast
    as the loop runs), from an MCAP recording's ``robot`` (left out: its only robot) or a
    ``galileo record`` capture; the commands the Robot sends reach ``device.commands``, and
    nothing acts on them. At the recording's end the link is lost (a reconnect plays it
    again). InvalidArgument, nothing started, for a file that cannot be replayed.
    """
    if not isinstance(path, (str, Path)):
        raise InvalidArgument(f"path must be a file's path, got {path!r}")
    replay = {"replay": str(path), "robot": robot}
    async with simulated_robot(
        navigating=False, clock=clock, sim_options=replay, **options
    ) as pair:
        yield pair


def recorded_statuses(path: str | Path, robot: str | None = None) -> list[GalileoStatus]:
    """Every status of a recording's raw bytes, decoded as a link decodes them, in order."""
    decoder = StatusDecoder()
    return [status for _, data in load_capture(path, robot) for status in decoder.feed(data)]
