"""Incremental status-frame decoder (host side) and encoder (device side)."""

from __future__ import annotations

import enum
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from ..models import GalileoStatus, StatusLayout
from .layouts import ENUM_FIELDS, HEADER, LAYOUTS, LENGTH_V1, LENGTH_V2, V2_DEFAULTS, Layout

__all__ = [
    "MAX_BUFFER",
    "MAX_COUNTED_GAP",
    "DecoderStats",
    "RawFrame",
    "StatusDecoder",
    "encode_status",
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


@dataclass
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
    """Precomputed per-layout decode path: unpack, map enum fields, build the field dict."""

    __slots__ = ("convert", "fields", "layout", "name", "stamp_index", "unpack_from")

    def __init__(self, layout: Layout) -> None:
        self.layout = layout
        self.name = layout.name
        self.fields = fields = layout.fields
        self.unpack_from = layout.struct.unpack_from
        self.stamp_index = fields.index("time_stamp") if "time_stamp" in fields else None
        # One dict display per layout, generated like dataclasses generates __init__: it
        # builds the 22-entry dict about twice as fast as dict(zip(...)) plus fix-ups.
        namespace: dict[str, Any] = {"layout": layout.name}
        items = []
        for index, field in enumerate(fields):
            if field in ENUM_FIELDS:
                namespace[f"map_{field}"] = _EnumMap(ENUM_FIELDS[field])
                items.append(f"{field!r}: map_{field}[values[{index}]]")
            else:
                items.append(f"{field!r}: values[{index}]")
        body = ", ".join(items)
        source = f"def convert(values):\n    return {{{body}, 'layout': layout}}\n"
        exec(source, namespace)
        self.convert: Callable[[tuple[Any, ...]], dict[str, Any]] = namespace["convert"]


_CONVERTERS = {name: _Converter(layout) for name, layout in LAYOUTS.items()}
_V2 = _CONVERTERS[StatusLayout.V2]
_V2_SIZE = LAYOUTS[StatusLayout.V2].frame_size


class StatusDecoder:
    """Bytes in, GalileoStatus out: resyncs on garbage, never raises on bad input."""

    def __init__(self, layout: StatusLayout | str | None = None) -> None:
        self._pinned = StatusLayout(layout) if layout is not None else None
        self._detected: StatusLayout | None = self._pinned
        self._run = 0  # frames of the detected layout decoded in a row
        self._buffer = bytearray()
        self._in_sync = True
        self._last_time_stamp: int | None = None
        self.stats = DecoderStats(layout=self._pinned)

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

    def feed(self, data: bytes | bytearray | memoryview) -> list[GalileoStatus]:
        """Consume bytes; return every complete status frame found in order."""
        trusted = GalileoStatus.trusted
        return [trusted(converter.convert(values)) for converter, values in self._frames(data)]

    def feed_raw(self, data: bytes | bytearray | memoryview) -> list[RawFrame]:
        """Like feed, but return (layout, raw field values in wire order) per frame."""
        return [(converter.name, values) for converter, values in self._frames(data)]

    def _frames(self, data: bytes | bytearray | memoryview) -> list[tuple[_Converter, Values]]:
        buf = self._buffer
        buf += data
        size = len(buf)
        out: list[tuple[_Converter, Values]] = []
        pos = 0
        v2_first = self._v2_first()
        while pos < size:
            start = buf.find(HEADER, pos)
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
                and buf.find(HEADER, pos + _HEADER_SIZE, end) < 0
            ):
                converter = _V2
            else:
                verdict, layout = self._frame_at(buf, pos, size)
                if verdict == _NEED_MORE:
                    break
                if verdict == _REJECT:
                    self._discard(len(HEADER))
                    pos += len(HEADER)
                    continue
                assert layout is not None
                converter = _CONVERTERS[layout.name]
                end = pos + layout.frame_size
            values = converter.unpack_from(buf, pos + _HEADER_SIZE)
            out.append((converter, values))
            self._count(converter, values)
            if converter is not _V2:
                v2_first = self._v2_first()
            pos = end
        del buf[:pos]
        if len(buf) > MAX_BUFFER:  # unreachable with valid lengths; kept as a hard bound
            self._discard(len(buf) - MAX_BUFFER)
            del buf[: len(buf) - MAX_BUFFER]
        return out

    def _count(self, converter: _Converter, values: Values) -> None:
        """Account for one accepted frame: layout run and time_stamp gaps."""
        stats = self.stats
        stats.frames += 1
        self._in_sync = True
        name = converter.name
        if self._detected is not name:
            self._detected = name
            stats.layout = name
            self._run = 0
        self._run += 1
        if converter.stamp_index is not None:
            time_stamp = values[converter.stamp_index]
            last = self._last_time_stamp
            if last is not None:
                gap = time_stamp - last - 1
                if 0 < gap <= MAX_COUNTED_GAP:
                    stats.lost_frames += gap
                elif gap:
                    stats.counter_resets += 1
            self._last_time_stamp = time_stamp

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

    def _frame_at(self, buf: bytearray, pos: int, size: int) -> tuple[int, Layout | None]:
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

    def _v1_variant(self, buf: bytearray, pos: int) -> StatusLayout:
        # Field 3 is a float voltage in v1 (huge int32 bits) and a small int in v1_charge;
        # a stale 0.0 V reading looks like charge 0, so an established v1 stream wins then.
        raw = int.from_bytes(buf[pos + 12 : pos + 16], "little", signed=True)
        if -1 <= raw <= 5 and not (raw == 0 and self._detected is StatusLayout.V1):
            return StatusLayout.V1_CHARGE
        return StatusLayout.V1

    def _check(self, buf: bytearray, pos: int, size: int, layout: Layout) -> int:
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


def _header_prefix_length(buf: bytearray, start: int, end: int) -> int:
    """Length of the longest suffix of buf[start:end] that is a proper prefix of HEADER."""
    for keep in range(min(len(HEADER) - 1, end - start), 0, -1):
        if buf[end - keep : end] == HEADER[:keep]:
            return keep
    return 0


def encode_status(status: GalileoStatus, layout: StatusLayout | str | None = None) -> bytes:
    """Encode a status as the robot sends it in ``layout`` (default: the status's own)."""
    name = StatusLayout(layout) if layout is not None else status.layout
    if name is StatusLayout.ROS:
        name = StatusLayout.V2
    target = LAYOUTS[name]
    source = LAYOUTS[StatusLayout.V2] if name is StatusLayout.V2_TRUNCATED else target
    values = []
    for field in source.fields:
        value = getattr(status, field)
        values.append(V2_DEFAULTS[field] if value is None else value)
    payload = source.struct.pack(*values)
    if name is StatusLayout.V2_TRUNCATED:
        payload = payload[: target.frame_size - _HEADER_SIZE]
    tail = b"\x00" if target.terminated else b""
    return HEADER + bytes((target.length_byte,)) + payload + tail
