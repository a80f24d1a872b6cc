"""Incremental status-frame decoder (host side) and encoder (device side)."""

from __future__ import annotations

import enum
import struct
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from .._wire import StatusLayout
from .layouts import ENUM_FIELDS, HEADER, LAYOUTS, LENGTH_V1, LENGTH_V2, Layout

if TYPE_CHECKING:
    from ..models import GalileoStatus

__all__ = [
    "MAX_BUFFER",
    "MAX_COUNTED_GAP",
    "DecoderStats",
    "RawFrame",
    "StatusDecoder",
]

#: Most bytes the decoder keeps between feeds; a frame is at most 92 bytes with lookahead.
MAX_BUFFER = 4096
#: A time_stamp jump larger than this (one minute at 30 Hz) is a counter reset, not loss.
MAX_COUNTED_GAP = 30 * 60
#: Frames of an unpinned unterminated layout seen in a row before one is accepted without
#: waiting for the next header: a single frame that lost its tail must not establish it.
TRUST_AFTER = 3

#: Raw field values of one frame, in the layout's wire order (ints and floats).
Values = tuple[Any, ...]
#: One frame as StatusDecoder.feed_raw returns it: its layout and its raw field values.
RawFrame = tuple[StatusLayout, Values]

_VALID_LENGTHS = frozenset((LENGTH_V1, LENGTH_V2))
_ACCEPT, _REJECT, _NEED_MORE = 0, 1, 2
_HEADER_SIZE = len(HEADER) + 1


@dataclass(slots=True)
class DecoderStats:
    """Counters of what the decoder accepted and threw away."""

    frames: int = 0
    bytes_discarded: int = 0
    resyncs: int = 0
    lost_frames: int = 0
    counter_resets: int = 0
    layout: StatusLayout | None = None


class _EnumMap(dict[int, Any]):
    """Raw wire int → enum member; an unknown value becomes a pseudo-member, not cached."""

    __slots__ = ("enum_type",)

    def __init__(self, enum_type: type[enum.IntEnum]) -> None:
        super().__init__(enum_type._value2member_map_)
        self.enum_type = enum_type

    def __missing__(self, raw: int) -> Any:
        return self.enum_type(raw)


class _Converter:
    """Precomputed per-layout decode path: unpack, then build the status in one call.

    ``build`` loads the status builders (and pydantic with GalileoStatus) on the first frame
    any layout decodes, not at import (docs/architecture.md, "Import cost").
    """

    __slots__ = ("build", "fields", "layout", "maps", "name", "stamp_index", "unpack_from")

    def __init__(self, layout: Layout) -> None:
        self.layout = layout
        self.name = layout.name
        self.fields = fields = layout.fields
        self.unpack_from = layout.struct.unpack_from
        self.stamp_index = fields.index("time_stamp") if "time_stamp" in fields else None
        self.maps = {f: _EnumMap(ENUM_FIELDS[f]) for f in fields if f in ENUM_FIELDS}
        self.build: Callable[[Values], GalileoStatus] = self._first_build

    def _first_build(self, values: Values) -> GalileoStatus:
        _load_builders()
        return self.build(values)


def _load_builders() -> None:
    """Give every converter its status builder (the first frame decoded calls this)."""
    global _V2_BUILD
    from ._build import status_builder

    for converter in _CONVERTERS.values():
        converter.build = status_builder(converter.name, converter.fields, converter.maps)
    _V2_BUILD = _V2.build


_CONVERTERS = {name: _Converter(layout) for name, layout in LAYOUTS.items()}
_V2 = _CONVERTERS[StatusLayout.V2]
_V2_NAME = StatusLayout.V2
_V2_UNPACK = _V2.unpack_from
_V2_BUILD = _V2.build
# What the single-frame path reads in place (it keeps nothing of ``data``).
_FLAT = (bytes, bytearray)
_V2_STAMP = LAYOUTS[StatusLayout.V2].fields.index("time_stamp")
# Runs of whole v2 frames (several frames per read: high simulator speed, a loop that
# fell behind, a capture) are checked and unpacked in one pass; the struct pads over
# header, length byte and terminator, so it yields exactly the 21 field values.
_RUN_MIN, _RUN_MAX = 4, 64
_V2_PADDED = struct.Struct("<4x" + LAYOUTS[StatusLayout.V2].struct.format.lstrip("<") + "x")
_RUN_BYTES = tuple(bytes((value,)) * _RUN_MAX for value in (*HEADER, LENGTH_V2, 0))
_V2_SIZE = LAYOUTS[StatusLayout.V2].frame_size


class StatusDecoder:
    """Bytes in, GalileoStatus out: resyncs on garbage, never raises on bad input."""

    # Attributes inside the object: one memory block less to fetch per frame, which counts
    # across a fleet (BENCHMARKS.md §2).
    __slots__ = (
        "__weakref__", "_buffer", "_detected", "_in_sync", "_last_time_stamp", "_pinned",
        "_run", "_steady", "stats",
    )  # fmt: skip

    def __init__(
        self, layout: StatusLayout | str | None = None, *, stats: DecoderStats | None = None
    ) -> None:
        """Decode ``layout`` (None: detect it), counting into ``stats`` (a new one if None)."""
        self._pinned = StatusLayout(layout) if layout is not None else None
        self._detected: StatusLayout | None = self._pinned
        self._run = 0  # frames of the detected layout decoded in a row, until trusted
        self._buffer = bytearray()
        self._in_sync = True
        # Whether a whole clean v2 frame may take feed_from's shortcut, which keeps no books
        # but the counters: nothing held back, in sync, v2 detected and trusted.
        self._steady = False
        self._last_time_stamp: int | None = None
        if stats is None:
            stats = DecoderStats()
        if self._pinned is not None:
            stats.layout = self._pinned
        self.stats = stats

    @property
    def layout(self) -> StatusLayout | None:
        """The pinned layout, else the one detected from the last good frame."""
        return self._detected

    @property
    def buffered(self) -> int:
        """Bytes held back waiting for the rest of a frame."""
        return len(self._buffer)

    def reset(self) -> None:
        """Forget partial data and the frame counter (after a reconnect)."""
        self._buffer.clear()
        self._last_time_stamp = None
        self._in_sync = True
        self._steady = self._is_steady()

    def feed(self, data: bytes | bytearray | memoryview) -> list[GalileoStatus]:
        """Consume bytes; return every complete status frame found in order."""
        return self.feed_from(data, len(data))

    def feed_from(self, buffer: bytes | bytearray | memoryview, size: int) -> list[GalileoStatus]:
        """Like ``feed(buffer[:size])``; a whole clean frame is read in place, not copied."""
        # The commonest read, 30 times a second per robot, inlined: one whole clean v2 frame
        # in a steady stream, tested exactly as _frames' own single-frame branch does.
        if (
            size == _V2_SIZE
            and self._steady
            and type(buffer) in _FLAT
            and buffer[_V2_SIZE - 1] == 0
            and buffer[3] == LENGTH_V2
            # The last header in the frame is its first: it starts there, none inside it
            # (a header cannot overlap its own first three bytes).
            and buffer.rfind(HEADER, 0, _V2_SIZE) == 0  # type: ignore[union-attr]
        ):
            values = _V2_UNPACK(buffer, _HEADER_SIZE)
            self.stats.frames += 1
            time_stamp = values[_V2_STAMP]
            last, self._last_time_stamp = self._last_time_stamp, time_stamp
            if last is not None and time_stamp != last + 1:
                self._count_gap(time_stamp - last - 1)
            return [_V2_BUILD(values)]
        v2, build_v2 = _V2_NAME, _V2_BUILD
        data = buffer if size == len(buffer) else buffer[:size]
        return [
            build_v2(values) if name is v2 else _CONVERTERS[name].build(values)
            for name, values in self._frames(data)
        ]

    def feed_raw(self, data: bytes | bytearray | memoryview) -> list[RawFrame]:
        """Like feed, but return (layout, raw field values in wire order) per frame."""
        return self._frames(data)

    def _frames(self, data: bytes | bytearray | memoryview) -> list[RawFrame]:
        held = self._buffer
        buf: bytes | bytearray
        if held or type(data) is not bytes:
            held += data
            buf = held
        else:
            buf = data  # nothing held back: scan the chunk itself, no copy
        size = len(buf)
        out: list[RawFrame] = []
        append, find = out.append, buf.find
        pos = run_from = 0
        v2_first = self._v2_first()
        while pos < size:
            if v2_first and pos >= run_from and size - pos >= _RUN_MIN * _V2_SIZE:
                count = self._v2_run(buf, pos, size, out)
                if count:
                    pos += count * _V2_SIZE
                    continue
                run_from = pos + _RUN_MAX * _V2_SIZE  # not a clean run: go frame by frame
            start = find(HEADER, pos)
            if start < 0:
                keep = _header_prefix_length(buf, max(pos, size - 2), size)
                self._discard(size - keep - pos)
                pos = size - keep
                break
            if start != pos:
                self._discard(start - pos)
                pos = start
            end = pos + _V2_SIZE
            # The common case, decided exactly as _frame_at would: a terminated v2 frame
            # holding nothing that looks like a header.
            if (
                v2_first
                and end <= size
                and buf[pos + 3] == LENGTH_V2
                and buf[end - 1] == 0
                and find(HEADER, pos + _HEADER_SIZE, end) < 0
            ):
                values = _V2_UNPACK(buf, pos + _HEADER_SIZE)
                append((_V2_NAME, values))
                self._count(_V2, values)
                pos = end
                continue
            verdict, layout = self._frame_at(buf, pos, size)
            if verdict == _NEED_MORE:
                break
            if verdict == _REJECT:
                self._discard(len(HEADER))
                pos += len(HEADER)
                continue
            assert layout is not None
            converter = _CONVERTERS[layout.name]
            values = converter.unpack_from(buf, pos + _HEADER_SIZE)
            append((layout.name, values))
            self._count(converter, values)
            v2_first = self._v2_first()
            pos += layout.frame_size
        self.stats.frames += len(out)
        if buf is held:
            del held[:pos]
        elif pos < size:
            held += buf[pos:]
        if len(held) > MAX_BUFFER:  # unreachable with valid lengths; kept as a hard bound
            self._discard(len(held) - MAX_BUFFER)
            del held[: len(held) - MAX_BUFFER]
        self._steady = self._is_steady()
        return out

    def _v2_run(self, buf: bytes | bytearray, pos: int, size: int, out: list[RawFrame]) -> int:
        """Accept a run of clean v2 frames at ``pos`` in one go (their count), else 0.

        Clean as the per-frame path means it: a header at every frame start and no other.
        """
        count = min((size - pos) // _V2_SIZE, _RUN_MAX)
        region = buf[pos : pos + count * _V2_SIZE]
        step = _V2_SIZE
        if (
            region.count(HEADER) != count
            or region[0::step] != _RUN_BYTES[0][:count]
            or region[1::step] != _RUN_BYTES[1][:count]
            or region[2::step] != _RUN_BYTES[2][:count]
            or region[3::step] != _RUN_BYTES[3][:count]
            or region[step - 1 :: step] != _RUN_BYTES[4][:count]
        ):
            return 0
        rows = list(_V2_PADDED.iter_unpack(region))
        name = _V2_NAME
        out += [(name, row) for row in rows]
        self._in_sync = True
        if self._detected is not name:
            self._detected = self.stats.layout = name
            self._run = 0
        self._run += count
        last = self._last_time_stamp
        first = rows[0][_V2_STAMP]
        final = rows[-1][_V2_STAMP]
        if (last is None or first == last + 1) and final - first == count - 1:
            stamps = [row[_V2_STAMP] for row in rows]
            if stamps == list(range(first, final + 1)):
                self._last_time_stamp = final
                return count
        for row in rows:
            time_stamp = row[_V2_STAMP]
            if last is not None and time_stamp != last + 1:
                self._count_gap(time_stamp - last - 1)
            last = time_stamp
        self._last_time_stamp = last
        return count

    def _count(self, converter: _Converter, values: Values) -> None:
        """Account for one accepted frame (feed's single-frame path has an inlined copy)."""
        self._in_sync = True
        name = converter.name
        if self._detected is not name:
            self._detected = self.stats.layout = name
            self._run = 0
        self._run += 1
        if converter.stamp_index is not None:
            time_stamp = values[converter.stamp_index]
            last, self._last_time_stamp = self._last_time_stamp, time_stamp
            if last is not None and time_stamp != last + 1:
                self._count_gap(time_stamp - last - 1)

    def _count_gap(self, gap: int) -> None:
        """Frames missing between two time_stamps; a backwards or huge jump is a reset."""
        if 0 < gap <= MAX_COUNTED_GAP:
            self.stats.lost_frames += gap
        else:
            self.stats.counter_resets += 1

    def _is_steady(self) -> bool:
        # What _count would then change for a v2 frame is already so: in sync, v2 detected
        # (so v2 is tried first), and a longer run would not change _trusted().
        return not self._buffer and self._in_sync and self._detected is _V2_NAME and self._trusted()

    def _v2_first(self) -> bool:
        """Whether _frame_at would try the v2 layout first for a 0x55 length byte."""
        if self._pinned is not None:
            return self._pinned is StatusLayout.V2
        return self._detected is not StatusLayout.V2_TRUNCATED

    def _discard(self, count: int) -> None:
        if count <= 0:
            return
        self.stats.bytes_discarded += count
        if self._in_sync:
            self.stats.resyncs += 1
            self._in_sync = False

    def _frame_at(self, buf: bytes | bytearray, pos: int, size: int) -> tuple[int, Layout | None]:
        if pos + _HEADER_SIZE > size:
            return _NEED_MORE, None
        length_byte = buf[pos + 3]
        if length_byte not in _VALID_LENGTHS:
            return _REJECT, None
        if self._pinned is not None:
            candidates = [self._pinned] if LAYOUTS[self._pinned].length_byte == length_byte else []
        elif length_byte == LENGTH_V1:
            if pos + 16 > size:
                return _NEED_MORE, None
            candidates = [self._v1_variant(buf, pos)]
        elif self._detected is StatusLayout.V2_TRUNCATED:
            candidates = [StatusLayout.V2_TRUNCATED, StatusLayout.V2]
        else:
            candidates = [StatusLayout.V2, StatusLayout.V2_TRUNCATED]
        for name in candidates:
            layout = LAYOUTS[name]
            verdict = self._check(buf, pos, size, layout)
            if verdict != _REJECT:
                return verdict, layout
        return _REJECT, None

    def _v1_variant(self, buf: bytes | bytearray, pos: int) -> StatusLayout:
        # Field 3 is a float voltage in v1 (huge int32 bits) and a small int in v1_charge;
        # a stale 0.0 V reading looks like charge 0, so an established v1 stream wins then.
        raw = int.from_bytes(buf[pos + 12 : pos + 16], "little", signed=True)
        if -1 <= raw <= 5 and not (raw == 0 and self._detected is StatusLayout.V1):
            return StatusLayout.V1_CHARGE
        return StatusLayout.V1

    def _check(self, buf: bytes | bytearray, pos: int, size: int, layout: Layout) -> int:
        end = pos + layout.frame_size
        if end > size:
            return _NEED_MORE
        if layout.terminated and buf[end - 1] != 0:
            return _REJECT
        # With no terminator only the next header confirms the frame's end; an
        # established layout is trusted when the next bytes have not arrived yet.
        confirm = not layout.terminated
        # A header inside the frame is either float bytes or the next frame after bytes
        # were lost; only the next frame starting right at `end` tells them apart. Every
        # occurrence counts: float bytes may come before the next frame's real header.
        embedded = buf.find(HEADER, pos + _HEADER_SIZE, end)
        while embedded >= 0:
            if embedded + 3 >= size or buf[embedded + 3] in _VALID_LENGTHS:
                confirm = True
                break
            embedded = buf.find(HEADER, embedded + 1, end)
        if not confirm:
            return _ACCEPT
        # Only a header with a valid length byte starts the next frame.
        following = bytes(buf[end : end + _HEADER_SIZE])
        if following[:3] != HEADER[: len(following)]:
            return _REJECT
        if len(following) == _HEADER_SIZE:
            return _ACCEPT if following[3] in _VALID_LENGTHS else _REJECT
        if embedded < 0 and layout.name is self._detected and self._trusted():
            return _ACCEPT
        return _NEED_MORE

    def _trusted(self) -> bool:
        return self._pinned is not None or self._run >= TRUST_AFTER


def _header_prefix_length(buf: bytes | bytearray, start: int, end: int) -> int:
    """Length of the longest suffix of buf[start:end] that is a proper prefix of HEADER."""
    for keep in range(min(len(HEADER) - 1, end - start), 0, -1):
        if buf[end - keep : end] == HEADER[:keep]:
            return keep
    return 0
