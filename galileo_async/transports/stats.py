"""What a link reports: its statistics, and the sink it feeds statuses and health into."""

from __future__ import annotations

import asyncio
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Protocol

from ..errors import GalileoConnectionError
from ..models import GalileoStatus, LinkState, StatusLayout
from ..protocol import DecoderStats

__all__ = ["LinkState", "LinkStats", "StatusSink", "clock_note", "clocks", "loop_clock"]


def loop_clock() -> Callable[[], float]:
    """The running loop's clock: time.monotonic itself on asyncio's own loop (no frame)."""
    clock = asyncio.get_running_loop().time
    if getattr(clock, "__func__", None) is asyncio.BaseEventLoop.time:
        return time.monotonic  # what asyncio's time() returns (a virtual clock is not this)
    return clock


def clocks() -> tuple[float, float]:
    """Now by the running loop's clock and by the real one: where a wait began, for clock_note."""
    return asyncio.get_running_loop().time(), time.monotonic()


def clock_note(began: tuple[float, float]) -> str:
    """A timeout message's tail: ``""``, or the real time passed when the loop's clock ran ahead.

    A virtual clock (galileo_async.testing) jumps to the next timer whenever its loop waits,
    also for an answer from outside the loop (another thread's loop, another process): such
    a timeout fires at once, and its "within N s" is the loop's time, not the real one.
    """
    loop_time, real_time = clocks()
    waited, real = loop_time - began[0], real_time - began[1]
    if real >= waited / 2:
        return ""
    return (
        f" (by the event loop's clock, which ran ahead: {real:.2f} s of real time passed;"
        " a virtual clock does not wait for an answer from outside its loop)"
    )


@dataclass(slots=True, init=False)
class LinkStats:
    """Counters and health of one link (read by users as ``robot.link``).

    ``state`` is the link's LinkState (the link keeps it; follow it with
    ``Robot.link_states()``); ``stale`` and ``connected`` derive from it and from
    ``transport_open`` (only the link writes both).

    A byte link's decoder counts frames, discards, resyncs, lost frames, counter resets
    and the layout into ``decoder``; they read through as this object's own attributes.
    """

    decoder: DecoderStats
    bytes_received: int
    reconnects: int
    commands_sent: int
    #: Queued commands dropped unwritten: a later command replaced them (a drive session's
    #: newer speed, an exit cancel before a newer goal) or a user stop withdrew them.
    commands_superseded: int
    #: The transport is open (a reopened port with no status yet included); read
    #: ``connected`` (it is shown as that).
    transport_open: bool = field(repr=False)
    state: LinkState
    last_frame_at: float | None = field(repr=False)
    #: The clock of last_frame_at: the link's event loop time once it opened.
    clock: Callable[[], float] = field(repr=False, compare=False)

    def __init__(
        self,
        *,
        decoder: DecoderStats | None = None,
        bytes_received: int = 0,
        reconnects: int = 0,
        commands_sent: int = 0,
        commands_superseded: int = 0,
        connected: bool = False,
        state: LinkState = LinkState.CONNECTING,
        last_frame_at: float | None = None,
        clock: Callable[[], float] = time.monotonic,
        **decoder_counts: Any,
    ) -> None:
        """``decoder_counts``: DecoderStats fields (``frames=3``) when ``decoder`` is None.

        ``connected``: the transport is open (``transport_open``).
        """
        self.decoder = DecoderStats(**decoder_counts) if decoder is None else decoder
        self.bytes_received = bytes_received
        self.reconnects = reconnects
        self.commands_sent = commands_sent
        self.commands_superseded = commands_superseded
        self.transport_open = connected
        self.state = state
        self.last_frame_at = last_frame_at
        self.clock = clock

    @property
    def connected(self) -> bool:
        """True while the transport is up (the link not closed)."""
        return self.transport_open and self.state is not LinkState.CLOSED

    @property
    def stale(self) -> bool:
        """True while the link is STALE: open, but no valid status for stale_timeout."""
        return self.state is LinkState.STALE

    @property
    def frames(self) -> int:
        """Valid frames (statuses) received."""
        return self.decoder.frames

    @property
    def bytes_discarded(self) -> int:
        """Bytes thrown away while looking for a frame."""
        return self.decoder.bytes_discarded

    @property
    def resyncs(self) -> int:
        """Times the decoder lost the frame boundary and searched again."""
        return self.decoder.resyncs

    @property
    def lost_frames(self) -> int:
        """Frames missing from the time_stamp sequence."""
        return self.decoder.lost_frames

    @property
    def counter_resets(self) -> int:
        """Times the robot's time_stamp started over."""
        return self.decoder.counter_resets

    @property
    def layout(self) -> StatusLayout | None:
        """The frame layout seen last, None before the first frame."""
        return self.decoder.layout

    @property
    def last_frame_age(self) -> float | None:
        """Seconds since the last valid frame (on ``clock``), or None before the first."""
        if self.last_frame_at is None:
            return None
        return self.clock() - self.last_frame_at


class StatusSink(Protocol):
    """What a link feeds (state.StatusStore is one): synchronous, cheap, never raising."""

    def update(self, status: GalileoStatus) -> None:
        """One valid status, in arrival order."""

    def link_changed(self, state: LinkState, error: GalileoConnectionError | None) -> None:
        """The link is now LOST (ConnectionLost), STALE (LinkStale) or UP again (None)."""

    def close(self) -> None:
        """Nothing will be fed any more."""
