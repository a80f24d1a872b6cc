"""StatusDecoder: golden vectors of docs/protocol.md §1, layout detection, resync, bounds, fuzz."""

from __future__ import annotations

import itertools
import random
import struct
from collections.abc import Iterable
from dataclasses import dataclass

import pytest
from hypothesis import assume, given
from hypothesis import strategies as st

from galileo_async.models import GalileoStatus, StatusLayout
from galileo_async.protocol import (
    HEADER,
    LAYOUTS,
    MAX_BUFFER,
    MAX_COUNTED_GAP,
    StatusDecoder,
    encode_status,
)
from tests.support import vectors as v
from tests.support.vectors import ALL_LAYOUTS, V1, V1C, V2, V2T, next_header, statuses, unambiguous


@dataclass(frozen=True)
class Case:
    """A byte stream, the statuses it holds, and the layout pin to decode it with."""

    name: str
    stream: bytes
    expected: tuple[GalileoStatus, ...]
    pin: StatusLayout | None = None
    lost_frames: int = 0

    @property
    def open_ended(self) -> bool:
        """Ends in a v2_truncated frame: only a following header may end it."""
        return self.expected[-1].layout is V2T


CASES = [
    Case("v2_example", v.V2_EXAMPLE, (v.V2_EXAMPLE_STATUS,)),
    Case("v2_active", v.V2_ACTIVE, (v.V2_ACTIVE_STATUS,)),
    # time_stamp 1 then 5: frames 2, 3 and 4 were lost.
    Case("v2_pair", v.V2_EXAMPLE + v.V2_ACTIVE, (v.V2_EXAMPLE_STATUS, v.V2_ACTIVE_STATUS), None, 3),
    Case("v1", v.V1_FRAME, (v.V1_STATUS,)),
    Case("v1_charge", v.V1_CHARGE_FRAME, (v.V1_CHARGE_STATUS,)),
    # Unpinned, the last unterminated frame is trusted without the next header only once
    # protocol.status.TRUST_AFTER frames of that layout came in a row.
    Case(
        "v2_truncated_run",
        (v.V2_TRUNCATED_A + v.V2_TRUNCATED_B) * 2,
        (v.V2_TRUNCATED_STATUS_A, v.V2_TRUNCATED_STATUS_B) * 2,
    ),
    Case("v2_pinned", v.V2_ACTIVE, (v.V2_ACTIVE_STATUS,), V2),
    Case("v1_pinned", v.V1_FRAME, (v.V1_STATUS,), V1),
    Case("v1_charge_pinned", v.V1_CHARGE_FRAME, (v.V1_CHARGE_STATUS,), V1C),
    Case("v2_truncated_pinned", v.V2_TRUNCATED_A, (v.V2_TRUNCATED_STATUS_A,), V2T),
    Case("v2_truncated_pinned_b", v.V2_TRUNCATED_B, (v.V2_TRUNCATED_STATUS_B,), V2T),
]
CASE_IDS = [case.name for case in CASES]

#: Garbage with a header carrying a bad length byte, ending in a partial header "CD EB"
#: that the real header after it overlaps.
GARBAGE = b"\x00\x13\x37garbage" + HEADER + b"\x07\xcd\xeb"
TERMINATED_TRAILER = b"\x11\x22\x33"
#: The start of the next frame: the only thing that can end a v2_truncated frame.
OPEN_TRAILER = HEADER + b"\x55\x00"


def feed_all(decoder: StatusDecoder, chunks: Iterable[bytes]) -> list[GalileoStatus]:
    """Feed every chunk, checking the buffer bound after each, and collect the output."""
    out: list[GalileoStatus] = []
    for chunk in chunks:
        out += decoder.feed(chunk)
        assert decoder.buffered <= MAX_BUFFER
    return out


def check(
    case: Case, decoder: StatusDecoder, out: list[GalileoStatus], *, discarded: int = 0
) -> None:
    assert out == list(case.expected)
    assert [s.layout for s in out] == [s.layout for s in case.expected]
    stats = decoder.stats
    assert stats.frames == len(case.expected)
    assert stats.bytes_discarded == discarded
    assert stats.resyncs == (1 if discarded else 0)
    assert stats.lost_frames == case.lost_frames
    assert stats.counter_resets == 0
    assert decoder.layout is case.expected[-1].layout
    assert stats.layout is case.expected[-1].layout


@pytest.mark.parametrize("case", CASES, ids=CASE_IDS)
def test_whole(case: Case) -> None:
    decoder = StatusDecoder(case.pin)
    check(case, decoder, feed_all(decoder, [case.stream]))
    assert decoder.buffered == 0


@pytest.mark.parametrize("case", CASES, ids=CASE_IDS)
def test_byte_by_byte(case: Case) -> None:
    decoder = StatusDecoder(case.pin)
    out = feed_all(decoder, [case.stream[i : i + 1] for i in range(len(case.stream))])
    check(case, decoder, out)


@pytest.mark.parametrize("case", CASES, ids=CASE_IDS)
def test_garbage_before(case: Case) -> None:
    for chunks in ([GARBAGE + case.stream], [GARBAGE, case.stream]):
        decoder = StatusDecoder(case.pin)
        check(case, decoder, feed_all(decoder, chunks), discarded=len(GARBAGE))
    stream = GARBAGE + case.stream
    decoder = StatusDecoder(case.pin)
    out = feed_all(decoder, [stream[i : i + 1] for i in range(len(stream))])
    check(case, decoder, out, discarded=len(GARBAGE))


@pytest.mark.parametrize("case", CASES, ids=CASE_IDS)
def test_trailing_bytes_after(case: Case) -> None:
    trailer = OPEN_TRAILER if case.open_ended else TERMINATED_TRAILER
    decoder = StatusDecoder(case.pin)
    out = feed_all(decoder, [case.stream + trailer])
    if case.open_ended:
        check(case, decoder, out)
        assert decoder.buffered == len(OPEN_TRAILER)  # the next frame, still incomplete
    else:
        check(case, decoder, out, discarded=len(TERMINATED_TRAILER))
        assert decoder.buffered == 0


@pytest.mark.parametrize("case", CASES, ids=CASE_IDS)
def test_split_at_every_offset(case: Case) -> None:
    for cut in range(len(case.stream) + 1):
        decoder = StatusDecoder(case.pin)
        check(case, decoder, feed_all(decoder, [case.stream[:cut], case.stream[cut:]]))


@pytest.mark.parametrize(
    ("frame", "status"),
    [
        (v.V2_EXAMPLE, v.V2_EXAMPLE_STATUS),
        (v.V2_ACTIVE, v.V2_ACTIVE_STATUS),
        (v.V1_FRAME, v.V1_STATUS),
        (v.V1_CHARGE_FRAME, v.V1_CHARGE_STATUS),
    ],
)
def test_terminated_frame_is_decoded_on_its_last_byte(frame: bytes, status: GalileoStatus) -> None:
    decoder = StatusDecoder()
    assert decoder.feed(frame[:-1]) == []
    assert decoder.feed(frame[-1:]) == [status]


def test_truncated_frame_waits_for_the_next_header() -> None:
    # No terminator: the frame ends where the next header starts (docs/protocol.md §1).
    decoder = StatusDecoder(V2T)
    assert decoder.feed(v.V2_TRUNCATED_A + b"\x00") == []  # not a header: rejected
    assert decoder.stats.bytes_discarded == len(v.V2_TRUNCATED_A) + 1
    decoder = StatusDecoder()
    assert decoder.feed(v.V2_TRUNCATED_A + HEADER) == []  # could still be a v2 frame
    # A header with its length byte ends B: one frame does not establish the layout.
    assert decoder.feed(v.V2_TRUNCATED_B[3:] + HEADER) == [v.V2_TRUNCATED_STATUS_A]
    assert decoder.feed(b"\x55") == [v.V2_TRUNCATED_STATUS_B]


# --- layout detection -------------------------------------------------------------------


def v1_frame(power: float, time_stamp: int = 9) -> bytes:
    """A v1 frame with the given power and otherwise distinctive values."""
    values = (1, 2, power, 6, 1, 2.5, 0, 0.5, 0.25, 0.5, 0.25, time_stamp)
    return HEADER + b"\x31" + struct.pack(v.V1_FORMAT, *values) + b"\x00"


def test_v1_and_v1_charge_told_apart_by_content() -> None:
    decoder = StatusDecoder()
    out = decoder.feed(v.V1_FRAME + v.V1_CHARGE_FRAME + v.V1_FRAME)
    assert [s.layout for s in out] == [V1, V1C, V1]
    assert out == [v.V1_STATUS, v.V1_CHARGE_STATUS, v.V1_STATUS]


def test_v1_with_zero_power_is_ambiguous_until_the_stream_is_known() -> None:
    # docs/protocol.md §1: a stale 0.0 V reading has the int32 bits of charge_status 0.
    zero = v1_frame(0.0)
    (fresh,) = StatusDecoder().feed(zero)
    assert fresh.layout is V1C
    assert fresh.charge_status == 0
    assert struct.pack("<f", fresh.power) == struct.pack("<i", 6)  # shifted fields
    decoder = StatusDecoder()
    first, second = decoder.feed(v1_frame(12.0, 8) + zero)
    assert (first.layout, second.layout) == (V1, V1)
    assert second.power == 0.0
    assert second.time_stamp == 9
    assert decoder.stats.lost_frames == 0
    (pinned,) = StatusDecoder("v1").feed(zero)
    assert pinned.layout is V1
    assert pinned.power == 0.0


def test_established_v1_stream_still_switches_on_a_charge_value() -> None:
    decoder = StatusDecoder()
    out = decoder.feed(v1_frame(12.0) + v.V1_CHARGE_FRAME)  # field 3 = 1: not a voltage
    assert [s.layout for s in out] == [V1, V1C]


def test_pinned_v1_charge_decodes_a_voltage_as_an_unknown_charge_state() -> None:
    (status,) = StatusDecoder(V1C).feed(v.V1_FRAME)
    assert status.layout is V1C
    assert status.charge_status is not None
    assert int(status.charge_status) == 0x41480000  # 12.5 V read as an int
    assert status.charge_status.known is False


def test_v2_and_v2_truncated_detected_and_switched() -> None:
    decoder = StatusDecoder()
    out = decoder.feed(v.V2_TRUNCATED_A + v.V2_TRUNCATED_B + v.V2_ACTIVE + v.V2_TRUNCATED_A)
    assert out[:3] == [v.V2_TRUNCATED_STATUS_A, v.V2_TRUNCATED_STATUS_B, v.V2_ACTIVE_STATUS]
    assert decoder.layout is V2
    # After v2, a 53-byte frame is told from a v2 frame once 89 bytes are in.
    assert decoder.feed(HEADER) == []
    # A header with its length byte ends B: one frame does not establish the layout.
    assert decoder.feed(v.V2_TRUNCATED_B[3:] + HEADER) == [v.V2_TRUNCATED_STATUS_A]
    assert decoder.feed(b"\x55") == [v.V2_TRUNCATED_STATUS_B]
    assert decoder.layout is V2T


@pytest.mark.parametrize(
    ("pin", "stream"),
    [
        (V2, v.V2_TRUNCATED_A + v.V2_TRUNCATED_B + HEADER),
        (V2, v.V1_FRAME),
        (V2T, v.V2_ACTIVE + v.V2_EXAMPLE),
        (V1, v.V2_ACTIVE),
        (V1C, v.V2_EXAMPLE),
    ],
)
def test_pinned_layout_rejects_other_layouts(pin: StatusLayout, stream: bytes) -> None:
    decoder = StatusDecoder(pin)
    assert feed_all(decoder, [stream]) == []
    assert decoder.stats.frames == 0
    assert decoder.stats.bytes_discarded == len(stream) - decoder.buffered
    assert decoder.layout is pin


def test_pinned_layout_accepts_string_and_enum() -> None:
    assert StatusDecoder("v1_charge").layout is V1C
    assert StatusDecoder(V2T).stats.layout is V2T
    assert StatusDecoder().layout is None
    with pytest.raises(ValueError, match="v3"):
        StatusDecoder("v3")


# --- frame counter ----------------------------------------------------------------------


def stamped(*time_stamps: int) -> bytes:
    return b"".join(encode_status(GalileoStatus(time_stamp=t)) for t in time_stamps)


@pytest.mark.parametrize(
    ("time_stamps", "lost", "resets"),
    [
        ((1, 2, 3), 0, 0),
        ((1, 2, 5, 6), 2, 0),
        ((10, 1, 2), 0, 1),  # serial node restarted
        ((7, 7), 0, 1),  # a repeat is not progress
        ((1, 2 + MAX_COUNTED_GAP), MAX_COUNTED_GAP, 0),
        ((1, 3 + MAX_COUNTED_GAP), 0, 1),
        ((2**32 - 2, 2**32 - 1, 0), 0, 1),
    ],
)
def test_lost_frames_and_counter_resets(
    time_stamps: tuple[int, ...], lost: int, resets: int
) -> None:
    decoder = StatusDecoder()
    assert len(decoder.feed(stamped(*time_stamps))) == len(time_stamps)
    assert (decoder.stats.lost_frames, decoder.stats.counter_resets) == (lost, resets)


def test_layouts_without_time_stamp_count_nothing() -> None:
    decoder = StatusDecoder()
    decoder.feed(v.V1_CHARGE_FRAME * 3 + v.V2_TRUNCATED_A * 3 + HEADER + b"\x55")
    assert decoder.stats.frames == 6
    assert (decoder.stats.lost_frames, decoder.stats.counter_resets) == (0, 0)


def test_reset_forgets_partial_frame_and_counter() -> None:
    decoder = StatusDecoder()
    decoder.feed(stamped(50) + stamped(51)[:40])
    assert decoder.buffered == 40
    decoder.reset()
    assert decoder.buffered == 0
    assert decoder.feed(stamped(1, 2)) == [
        GalileoStatus(**{**v.V2_EXAMPLE_STATUS.model_dump(), "time_stamp": t}) for t in (1, 2)
    ]
    assert (decoder.stats.lost_frames, decoder.stats.counter_resets) == (0, 0)
    assert decoder.layout is V2  # the layout survives a reconnect


def test_bytearray_reads_decode_like_bytes_and_are_not_kept() -> None:
    frames = stamped(1, 2, 3)
    decoder = StatusDecoder()
    single = bytearray(frames[: len(frames) // 3])
    assert decoder.feed(single) == StatusDecoder().feed(bytes(single))
    # A reused read buffer: what the decoder holds back must be its own copy.
    buffer = bytearray(frames[len(frames) // 3 : len(frames) // 3 + 50])
    assert decoder.feed(buffer) == []
    buffer[:] = b"\xff" * len(buffer)
    assert [s.time_stamp for s in decoder.feed(frames[len(frames) // 3 + 50 :])] == [2, 3]
    assert decoder.stats.bytes_discarded == 0


def test_feed_from_reads_only_the_first_size_bytes_of_a_reused_buffer() -> None:
    frames = stamped(1, 2, 3)
    size = len(frames) // 3
    buffer = bytearray(HEADER * 100)  # a header-laden tail past `size`
    decoder = StatusDecoder()
    for stamp, start in ((1, 0), (2, size)):
        buffer[:size] = frames[start : start + size]
        assert [s.time_stamp for s in decoder.feed_from(buffer, size)] == [stamp]
    # A partial read is held back as a copy; the buffer is then overwritten.
    buffer[:50] = frames[2 * size : 2 * size + 50]
    assert decoder.feed_from(buffer, 50) == []
    assert decoder.buffered == 50
    buffer[:] = b"\xff" * len(buffer)
    assert [s.time_stamp for s in decoder.feed(frames[2 * size + 50 :])] == [3]
    assert decoder.stats.bytes_discarded == 0
    assert decoder.feed_from(buffer, 0) == []


# --- resync -------------------------------------------------------------------------------


def active(time_stamp: int, **changes: float) -> GalileoStatus:
    """The busy golden status with another time_stamp (and optional field changes)."""
    return v.V2_ACTIVE_STATUS.model_copy(update={"time_stamp": time_stamp, **changes})


def frames_of(*items: GalileoStatus) -> bytes:
    return b"".join(encode_status(s) for s in items)


def test_garbage_between_frames() -> None:
    decoder = StatusDecoder()
    out = decoder.feed(frames_of(active(1)) + b"junk" + frames_of(active(2)) + b"\x00" * 7)
    assert out == [active(1), active(2)]
    assert (decoder.stats.bytes_discarded, decoder.stats.resyncs) == (11, 2)


def test_bad_length_bytes() -> None:
    junk = HEADER + b"\x30" + HEADER + b"\x00" + HEADER + b"\xff" + HEADER + b"\x54"
    stream = junk + frames_of(active(1)) + HEADER + b"\x56\x00" + frames_of(active(2))
    decoder = StatusDecoder()
    assert feed_all(decoder, [stream]) == [active(1), active(2)]
    assert decoder.stats.bytes_discarded == len(junk) + 5
    assert decoder.stats.resyncs == 2


@pytest.mark.parametrize("last_byte", [b"\x01", b"\xcd", b""])
def test_missing_terminator(last_byte: bytes) -> None:
    broken = frames_of(active(1))[:-1] + last_byte
    decoder = StatusDecoder()
    assert decoder.feed(broken + frames_of(active(2), active(3))) == [active(2), active(3)]
    assert decoder.stats.bytes_discarded == len(broken)
    assert decoder.stats.lost_frames == 0  # no earlier frame to measure against


@pytest.mark.parametrize(
    ("intact", "pin"),
    [
        ([active(t) for t in (2, 3, 4)], None),
        ([active(t) for t in (2, 3, 4)], V2),
        ([v.V1_STATUS.model_copy(update={"time_stamp": t}) for t in (2, 3, 4)], None),
        ([v.V1_CHARGE_STATUS] * 3, V1C),
    ],
    ids=["v2", "v2_pinned", "v1", "v1_charge_pinned"],
)
def test_frame_losing_bytes_in_the_middle(intact: list[GalileoStatus], pin: StatusLayout) -> None:
    frame = encode_status(intact[0].model_copy(update={"time_stamp": 1}))
    tail = frames_of(*intact)
    for start in range(len(frame)):
        for lost in range(1, min(41, len(frame) - start)):
            broken = frame[:start] + frame[start + lost :]
            decoder = StatusDecoder(pin)
            out = decoder.feed(broken + tail)
            extra = 0
            if pin is None and len(broken) == 53 and broken[:4] == HEADER + b"\x55":
                # Byte for byte a v2_truncated frame: no decoder can tell (docs/protocol.md §1).
                assert out[0].layout is V2T
                out, extra = out[1:], 1
            assert out == intact, (start, lost)
            assert decoder.stats.frames == len(intact) + extra
            assert decoder.stats.bytes_discarded == len(broken) - 53 * extra


# A float whose bytes are CD EB D7 3F (1.6869) puts a header inside a frame; the byte after
# it (0x3F) is not a length byte. CD EB D7 31 (6.28e-9) is followed by a valid one.
HEADER_FLOAT = struct.unpack("<f", HEADER + b"\x3f")[0]
HEADER_FLOAT_V1_LENGTH = struct.unpack("<f", HEADER + b"\x31")[0]


def test_header_inside_float_payload_bytes() -> None:
    sent = [active(t, current_pose_x=HEADER_FLOAT) for t in range(1, 6)]
    stream = frames_of(*sent)
    assert stream.count(HEADER) == 10
    for chunk in (1, 7, 89, len(stream)):
        decoder = StatusDecoder()
        out = feed_all(decoder, [stream[i : i + chunk] for i in range(0, len(stream), chunk)])
        assert out == sent
        assert decoder.stats.bytes_discarded == 0


def test_header_with_valid_length_inside_payload_waits_for_the_next_frame() -> None:
    status = active(1, current_speed_theta=HEADER_FLOAT_V1_LENGTH)
    frame = encode_status(status)
    for decoder in (StatusDecoder(), StatusDecoder(V2)):
        assert decoder.feed(frame) == []  # a frame start inside? only the next header tells
        assert decoder.buffered == len(frame)
        assert decoder.feed(frames_of(active(2))) == [status, active(2)]
        # Even in an established stream: the frame could have lost bytes.
        assert decoder.feed(frame) == []
        assert decoder.feed(HEADER[:2]) == []
        assert decoder.feed(HEADER[2:] + b"\x55") == [status]


def test_frame_losing_bytes_before_a_header_float_is_dropped() -> None:
    # The next frame's header must be seen even behind a header-like float.
    sent = [active(t, current_pose_x=HEADER_FLOAT) for t in range(1, 5)]
    frame = encode_status(sent[0])
    tail = frames_of(*sent[1:])
    for start in range(len(frame)):
        for lost in range(1, len(frame) - start):
            broken = frame[:start] + frame[start + lost :]
            out = StatusDecoder().feed(broken + tail)
            if len(broken) == 53 and broken[:4] == HEADER + b"\x55":
                out = out[1:]  # indistinguishable from a v2_truncated frame
            assert out == sent[1:], (start, lost)


# --- bounded buffer ---------------------------------------------------------------------


@pytest.mark.parametrize(
    "flood",
    [
        (HEADER + b"\x55") * 100_000,
        (HEADER + b"\x31") * 100_000,
        HEADER * 100_000,
        bytes(range(256)) * 8_000,
        b"\xcd" * 1_000_000,
    ],
    ids=["v2_headers", "v1_headers", "bare_headers", "counting", "cd"],
)
def test_buffer_stays_bounded_under_floods(flood: bytes) -> None:
    for chunk in (len(flood), 65536, 4093):
        decoder = StatusDecoder()
        feed_all(decoder, [flood[i : i + chunk] for i in range(0, len(flood), chunk)])
        assert decoder.feed(frames_of(active(1))) == [active(1)]


def test_buffer_stays_bounded_under_megabytes_of_random_bytes() -> None:
    data = random.Random(2).randbytes(4_000_000)
    decoder = StatusDecoder()
    out = feed_all(decoder, [data])
    out += feed_all(decoder, [data[i : i + 3001] for i in range(0, len(data), 3001)])
    assert decoder.stats.frames == len(out)
    assert MAX_BUFFER >= 92  # room for a v2 frame and a following header


# --- hypothesis: round trips and fuzz -------------------------------------------------------


def chunked(data: st.DataObject, stream: bytes) -> list[bytes]:
    cuts = sorted(data.draw(st.lists(st.integers(0, len(stream)), max_size=8), label="cuts"))
    edges = [0, *cuts, len(stream)]
    return [stream[a:b] for a, b in itertools.pairwise(edges)]


def check_accounting(decoder: StatusDecoder, fed: int, out: list[GalileoStatus]) -> None:
    """Every byte fed was decoded as part of a frame, discarded, or is still buffered."""
    used = sum(LAYOUTS[s.layout].frame_size for s in out)
    assert used + decoder.stats.bytes_discarded + decoder.buffered == fed
    assert decoder.stats.frames == len(out)


ANY_FRAME = st.sampled_from(ALL_LAYOUTS).flatmap(statuses).map(encode_status)


def _flip(frame: bytes, bits: list[int]) -> bytes:
    out = bytearray(frame)
    for bit in bits:
        out[bit // 8 % len(out)] ^= 1 << (bit % 8)
    return bytes(out)


CORRUPTION = st.lists(
    st.one_of(
        st.binary(max_size=40),
        st.sampled_from([HEADER, HEADER + b"\x55", HEADER + b"\x31", b"\x00", b"\xcd\xeb"]),
        # A v2 header 36 bytes before the end: 89 bytes on, a 53-byte frame ends.
        st.binary(min_size=32, max_size=32).map(lambda b: HEADER + b"\x55" + b),
        st.tuples(ANY_FRAME, st.integers(0, 89), st.integers(0, 89)).map(
            lambda t: t[0][min(t[1:]) : max(t[1:])]
        ),
        st.tuples(ANY_FRAME, st.lists(st.integers(0, 711), min_size=1, max_size=4)).map(
            lambda t: _flip(*t)
        ),
    ),
    max_size=10,
).map(b"".join)


@given(st.data())
def test_intact_frames_after_corruption_are_recovered(data: st.DataObject) -> None:
    """The exact guarantee, for intact frames of one layout with no header inside them.

    All of them are decoded, except that for 53-byte layouts decoded without a pin, a
    header at the end of the corruption may start a false 89-byte v2 frame that ends
    exactly at the second intact frame and so swallows the first. A v2_truncated frame
    needs the next header to end it, and (before the layout is known) 89 bytes in the
    buffer, so those streams get three or more frames and a trailing header.
    """
    layout = data.draw(st.sampled_from(ALL_LAYOUTS), label="layout")
    pin = data.draw(st.sampled_from([None, layout]), label="pin")
    count = data.draw(st.integers(3 if layout is V2T else 1, 5), label="count")
    intact = data.draw(st.lists(unambiguous(layout), min_size=count, max_size=count))
    frames = [encode_status(s) for s in intact]
    assume(all(HEADER not in f[1:] for f in frames))
    corruption = data.draw(CORRUPTION, label="corruption")
    trailer = next_header(layout) if layout is V2T else b""
    stream = corruption + b"".join(frames) + trailer
    decoder = StatusDecoder(pin)
    out = feed_all(decoder, chunked(data, stream))
    guaranteed = count if (pin is not None or layout is V2) else count - 1
    assert out[len(out) - guaranteed :] == intact[count - guaranteed :]
    check_accounting(decoder, len(stream), out)


def test_false_v2_frame_may_swallow_the_first_intact_53_byte_frame() -> None:
    # The documented exception to the recovery guarantee: "CD EB D7 55" 36 bytes before a
    # v1 frame reads as a v2 frame ending exactly where the next v1 frame starts.
    corruption = HEADER + b"\x55" + bytes(range(1, 33))
    decoder = StatusDecoder()
    out = decoder.feed(corruption + v.V1_FRAME * 3)
    assert [s.layout for s in out] == [V2, V1, V1]
    assert out[1:] == [v.V1_STATUS] * 2
    assert StatusDecoder(V1).feed(corruption + v.V1_FRAME * 3) == [v.V1_STATUS] * 3


@given(st.binary(max_size=2000), st.data())
def test_random_bytes_never_raise(garbage: bytes, data: st.DataObject) -> None:
    pin = data.draw(st.sampled_from([None, *ALL_LAYOUTS]), label="pin")
    decoder = StatusDecoder(pin)
    out = feed_all(decoder, chunked(data, garbage))
    check_accounting(decoder, len(garbage), out)


@given(st.lists(ANY_FRAME, min_size=1, max_size=6), st.data())
def test_bit_flips_never_raise(frames: list[bytes], data: st.DataObject) -> None:
    stream = b"".join(frames)
    bits = data.draw(st.lists(st.integers(0, 8 * len(stream) - 1), max_size=6), label="bits")
    flipped = _flip(stream, bits)
    decoder = StatusDecoder()
    out = feed_all(decoder, chunked(data, flipped))
    check_accounting(decoder, len(flipped), out)


def test_one_cut_v2_frame_does_not_establish_v2_truncated() -> None:
    # A v2 frame that lost its tail looks like one v2_truncated frame; the intact v2 frame
    # after it must not be cut at 53 bytes just because a read ended there.
    fragment = v.V2_EXAMPLE[:53]
    decoder = StatusDecoder()
    out = decoder.feed(fragment + v.V2_ACTIVE[:53])
    out += decoder.feed(v.V2_ACTIVE[53:] + v.V2_ACTIVE)
    assert out[1:] == [v.V2_ACTIVE_STATUS, v.V2_ACTIVE_STATUS]
    assert decoder.layout is V2
