"""What a link reports: its statistics, and the sink it feeds statuses and health into."""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Protocol

from ..errors import GalileoConnectionError, LinkStale
from ..models import GalileoStatus
from ..protocol import DecoderStats

__all__ = ["LinkStats", "StatusSink"]


@dataclass(slots=True)
class LinkStats(DecoderStats):
    """Counters and health of one link (read by users as ``robot.link``).

    A byte link's decoder counts frames, discards, resyncs, lost frames, counter resets
    and the layout straight into it.
    """

    bytes_received: int = 0
    reconnects: int = 0
    commands_sent: int = 0
    connected: bool = False
    stale: bool = False
    last_frame_at: float | None = field(default=None, repr=False)

    @property
    def last_frame_age(self) -> float | None:
        """Seconds since the last valid frame (time.monotonic), or None before the first."""
        if self.last_frame_at is None:
            return None
        return time.monotonic() - self.last_frame_at


class StatusSink(Protocol):
    """What a link feeds (state.StatusStore is one): synchronous, cheap, never raising."""

    def update(self, status: GalileoStatus) -> None:
        """One valid status, in arrival order."""

    def connection_lost(self, exc: GalileoConnectionError) -> None:
        """The transport dropped."""

    def connection_restored(self) -> None:
        """The transport is up again."""

    def link_stale(self, exc: LinkStale) -> None:
        """No valid status for stale_timeout."""

    def link_fresh(self) -> None:
        """Valid statuses arrive again after the link was stale."""

    def close(self) -> None:
        """Nothing will be fed any more."""
