"""Channel: one link kind's connection to the robot, under the one Link.

A channel is small (httpcore's backend shape): the Link owns the command queue, pacing,
supersession, reconnect, the stale watchdog and the one LinkState; a channel only

- ``await open(feed)``: connects (GalileoConnectionError if it cannot) and from then on
  reports to ``feed``: decoded statuses (``feed.received(statuses)`` once per read, or
  ``feed.status(status)`` once per status for a channel without a decoder; a byte
  channel's protocol writes ``received`` out: it stamps ``feed.stats.last_frame_at`` and
  calls ``feed.deliver(status)`` per status) and the loss of its connection
  (``feed.lost(exc)``, once). The Link calls it again to reconnect;
- ``accepts(command)``: raises InvalidArgument or NotSupported for a command it cannot
  write, before anything is queued (the Link's ``enqueue`` and ``send`` call it);
- ``await write(command)``: writes one command and returns its answer (None on a byte
  channel, the REST answer on HTTP); raises ConnectionLost while it is down;
- ``pending_bytes()``: bytes the transport holds unsent (the Link writes only into an
  empty buffer; 0 when it cannot tell);
- ``abandon(reason)``: gives a silent connection up now, without reporting it lost (the
  Link does that);
- ``await close()``: closes the connection and whatever the channel owns (bounded).

What a channel can do is data, its ``capabilities``; ``decoder_stats`` are the counters its
decoder keeps (read as ``LinkStats.decoder``). ``stale_message`` and ``on_stale`` let a
channel say why it is silent and react (UDP re-registers); ``map_target_count`` tells the
robot's map size where the channel can read it.
"""

from __future__ import annotations

import abc
import logging
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Protocol

from ..models import GalileoStatus
from ..protocol import Command, DecoderStats

if TYPE_CHECKING:
    from .stats import LinkStats

__all__ = ["Capabilities", "Channel", "Feed", "frames_log"]

#: Raw frames in hex, both directions, at DEBUG only.
frames_log = logging.getLogger("galileo_async.transports.frames")


@dataclass(frozen=True, slots=True)
class Capabilities:
    """What a channel can do; the robot layer decides from these, never from the class."""

    #: Writes a Velocity (a Twist) itself; otherwise the robot writes f/b and c/d.
    velocity: bool = False
    #: Writes a PoseGoal itself; otherwise the robot adds a target and goes to it.
    pose_goals: bool = False
    #: Answers REST calls (the vendor's HTTP API): ``write`` returns their answers.
    rest_api: bool = False
    #: Carries the serial protocol's bytes (a connector can be opened for it).
    byte_stream: bool = False


class Feed(Protocol):
    """What a channel reports to (the Link): synchronous, cheap, never raising."""

    #: The link's counters: a channel counts ``bytes_received`` into them.
    stats: LinkStats
    #: Takes one valid status once ``stats.last_frame_at`` is stamped for its read:
    #: ``received`` written out, for a channel's per-read hot path.
    deliver: Callable[[GalileoStatus], None]

    def received(self, statuses: Sequence[GalileoStatus]) -> None:
        """Valid statuses of one read, in order, already counted by the channel's decoder."""

    def status(self, status: GalileoStatus) -> None:
        """One valid status from a channel without a decoder (the feed counts it)."""

    def lost(self, exc: BaseException | None) -> None:
        """The connection dropped (None: closed by the peer); at most once per open."""


class Channel(abc.ABC):
    """One link kind's connection; subclasses implement open, write and close."""

    __slots__ = ()

    #: What the channel can do (class data; a channel may set its own per instance).
    capabilities: Capabilities = Capabilities()
    #: A name for logs and reprs (the URL).
    name: str | None = None

    @property
    @abc.abstractmethod
    def decoder_stats(self) -> DecoderStats:
        """The counters the channel's decoder keeps (or a DecoderStats the feed counts into)."""

    @abc.abstractmethod
    async def open(self, feed: Feed) -> None:
        """Connect and report to ``feed``; GalileoConnectionError if it cannot."""

    def accepts(self, command: Command) -> None:
        """Raise InvalidArgument or NotSupported for a command this channel cannot write."""
        return None  # default: every command

    @abc.abstractmethod
    async def write(self, command: Command) -> Any:
        """Write one command and return its answer; ConnectionLost while down."""

    def pending_bytes(self) -> int:
        """Bytes the transport holds unsent; 0 when it cannot tell."""
        return 0

    @abc.abstractmethod
    def abandon(self, reason: str) -> None:
        """Drop the current connection now without reporting it lost (the Link does)."""

    @abc.abstractmethod
    async def close(self) -> None:
        """Close the connection and whatever the channel owns (bounded)."""

    def stale_message(self, silent: float) -> str:
        """What LinkStale says after ``silent`` seconds without a valid status."""
        return f"no valid status frame for {silent:.2f} s"

    def on_stale(self) -> None:
        """The link just turned stale (the store was told); default: nothing."""
        return None

    def map_target_count(self) -> int | None:
        """How many targets the robot's map has, when the channel can tell (once open)."""
        return None

    def add_raw_listener(self, listener: Callable[[bytes], None]) -> bool:
        """Call ``listener(data)`` with every read's bytes; False: this channel has none."""
        return False

    def remove_raw_listener(self, listener: Callable[[bytes], None]) -> None:
        """Stop calling ``listener`` (no-op if it is not one)."""
        return None
