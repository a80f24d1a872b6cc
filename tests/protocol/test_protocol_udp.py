"""The UDP port's status frames (docs/protocol.md §7.2-7.3) and parser (§7.5): vectors, fuzz."""

from __future__ import annotations

import struct

import pytest
from hypothesis import given
from hypothesis import strategies as st

from galileo_async.models import (
    ChargeStatus,
    GalileoStatus,
    MapStatus,
    NavStatus,
    StatusLayout,
    TargetStatus,
    VisualStatus,
)
from galileo_async.protocol import (
    UDP_LAYOUTS,
    DatagramCommandDecoder,
    Forward,
    Goto,
    StatusEncoder,
    UdpStatusDecoder,
    encode_status,
)
from galileo_async.protocol.udp import encode_env_frame

UDP_V1, UDP_V2 = StatusLayout.UDP_V1, StatusLayout.UDP_V2
HEADER = bytes.fromhex("cdebd7")
# The vendor's packing, spelled out again (udp_status_service.py): x, y, 0.0, power,
# flags, 3 pad bytes, angle, target_status, target_num_id, charge_status, loop_status
# [, target_distance].
NOETIC = struct.Struct("<3sB4fB3xf4if")
OLDER = struct.Struct("<3sB4fB3xf4i")

#: A robot navigating to target 3, tracking, gba running: flags 0x01|0x04|0x08|0x20.
FRAME_48 = NOETIC.pack(HEADER, 0x2C, 1.5, -2.0, 0.0, 24.5, 0x2D, 0.5, 1, 3, 0, 0, 1.25)
FRAME_44 = OLDER.pack(HEADER, 0x28, 1.5, -2.0, 0.0, 24.5, 0x2D, 0.5, 1, 3, 0, 0)
ENV_FRAME = struct.pack("<3sB8f", HEADER, 0x20, 22.0, 45.0, 0.0, 5.0, 8.0, 10.0, 0.0, 40.0)

EXPECTED = GalileoStatus(
    layout=UDP_V2,
    nav_status=NavStatus.OPEN,
    visual_status=VisualStatus.TRACKING,
    map_status=MapStatus.IDLE,
    gc_status=0,
    gba_status=1,
    charge_status=ChargeStatus.FREE,
    loop_status=0,
    power=24.5,
    target_num_id=3,
    target_status=TargetStatus.WORKING,
    target_distance=1.25,
    current_pose_x=1.5,
    current_pose_y=-2.0,
    current_angle=0.5,
)


def test_frame_sizes_match_the_vendor() -> None:
    assert len(FRAME_48) == 48
    assert FRAME_48[3] == len(FRAME_48) - 4
    assert len(FRAME_44) == 44
    assert FRAME_44[3] == len(FRAME_44) - 4
    assert UDP_LAYOUTS[UDP_V2].frame_size == 48
    assert UDP_LAYOUTS[UDP_V1].frame_size == 44


def test_decodes_the_48_byte_frame() -> None:
    decoder = UdpStatusDecoder()
    assert decoder.feed(FRAME_48) == [EXPECTED]
    assert decoder.stats.frames == 1
    assert decoder.stats.layout is UDP_V2


def test_decodes_the_44_byte_frame_without_a_distance() -> None:
    (status,) = UdpStatusDecoder().feed(FRAME_44)
    assert status == EXPECTED.model_copy(update={"layout": UDP_V1, "target_distance": None})


def test_fields_the_frame_lacks_are_none() -> None:
    (status,) = UdpStatusDecoder().feed(FRAME_48)
    for field in (
        "angle_goal_status", "control_speed_x", "control_speed_theta", "current_speed_x",
        "current_speed_theta", "time_stamp", "busy_status",
    ):  # fmt: skip
        assert getattr(status, field) is None, field
    assert not status.is_busy  # unknown busy never backs off


@pytest.mark.parametrize(
    ("flags", "nav", "mapping", "visual", "gc", "gba"),
    [
        (0x00, 0, 0, VisualStatus.OFF, 0, 0),
        (0x01, 1, 0, VisualStatus.OFF, 0, 0),
        (0x02, 0, 1, VisualStatus.OFF, 0, 0),
        # visual initialising or lost: both 0x04 without 0x08; read as not initialised.
        (0x04, 0, 0, VisualStatus.NOT_INITIALISED, 0, 0),
        (0x0C, 0, 0, VisualStatus.TRACKING, 0, 0),
        (0x10, 0, 0, VisualStatus.OFF, 1, 0),
        (0x20, 0, 0, VisualStatus.OFF, 0, 1),
        (0x3F, 1, 1, VisualStatus.TRACKING, 1, 1),
    ],
)
def test_flags_byte(
    flags: int, nav: int, mapping: int, visual: VisualStatus, gc: int, gba: int
) -> None:
    frame = NOETIC.pack(HEADER, 0x2C, 0.0, 0.0, 0.0, 24.0, flags, 0.0, 0, -1, 0, 0, -1.0)
    (status,) = UdpStatusDecoder().feed(frame)
    assert (status.nav_status, status.map_status) == (nav, mapping)
    assert status.visual_status is visual
    assert (status.gc_status, status.gba_status) == (gc, gba)


@pytest.mark.parametrize(
    ("visual", "flags"),
    [(-1, 0x00), (0, 0x04), (1, 0x0C), (2, 0x04)],  # lost (2) sends what initialising does
)
def test_encoder_packs_the_flags_as_the_vendor(visual: int, flags: int) -> None:
    status = EXPECTED.model_copy(update={"visual_status": VisualStatus(visual), "gba_status": 0})
    frame = encode_status(status, UDP_V2)
    assert frame[20] == flags | 0x01  # navigating


def test_encoder_matches_the_vendor_bytes() -> None:
    assert encode_status(EXPECTED, UDP_V2) == FRAME_48
    assert encode_status(EXPECTED, UDP_V1) == FRAME_44
    assert StatusEncoder(UDP_V2).frame([None] * 20)[:4] == HEADER + b"\x2c"


def test_environment_frames_are_skipped_not_discarded() -> None:
    decoder = UdpStatusDecoder()
    assert encode_env_frame((22.0, 45.0, 0.0, 5.0, 8.0, 10.0, 0.0, 40.0)) == ENV_FRAME
    assert decoder.feed(ENV_FRAME) == []
    assert decoder.feed(FRAME_48) == [EXPECTED]
    assert decoder.skipped_frames == 1
    assert decoder.stats.bytes_discarded == 0
    assert decoder.stats.frames == 1


def test_several_frames_in_one_datagram() -> None:
    decoder = UdpStatusDecoder()
    out = decoder.feed(FRAME_48 + ENV_FRAME + FRAME_44)
    assert [s.layout for s in out] == [UDP_V2, UDP_V1]
    assert decoder.stats.bytes_discarded == 0


@pytest.mark.parametrize(
    "datagram",
    [
        b"",
        b"xq",
        HEADER,
        HEADER + b"\x2c",
        FRAME_48[:-1],  # short
        FRAME_48 + b"\x00",  # a trailing byte: the frame does not end where the datagram does
        HEADER + b"\x55" + FRAME_48[4:],  # a serial length byte
    ],
)
def test_bad_datagrams_yield_nothing(datagram: bytes) -> None:
    decoder = UdpStatusDecoder()
    assert decoder.feed(datagram) == []
    assert decoder.stats.frames == 0
    assert decoder.skipped_frames == 0
    assert (decoder.stats.bytes_discarded > 0) is bool(datagram)


def test_garbage_before_a_frame_is_discarded_and_counted() -> None:
    decoder = UdpStatusDecoder()
    assert decoder.feed(b"\x01\x02\x03" + FRAME_48) == [EXPECTED]
    assert decoder.stats.bytes_discarded == 3


def test_nothing_is_carried_between_datagrams() -> None:
    decoder = UdpStatusDecoder()
    assert decoder.feed(FRAME_48[:20]) == []
    assert decoder.feed(FRAME_48[20:]) == []
    assert decoder.feed(FRAME_48) == [EXPECTED]


F32 = st.floats(width=32, allow_nan=False, allow_infinity=False)
I32 = st.integers(-(2**31), 2**31 - 1)


@st.composite
def udp_statuses(draw: st.DrawFn, layout: StatusLayout) -> GalileoStatus:
    """Statuses a UDP frame represents exactly (flags-level fields, as decoded)."""
    visual = draw(
        st.sampled_from([VisualStatus.OFF, VisualStatus.NOT_INITIALISED, VisualStatus.TRACKING])
    )
    fields = {
        "layout": layout,
        "nav_status": NavStatus(draw(st.integers(0, 1))),
        "visual_status": visual,
        "map_status": MapStatus(draw(st.integers(0, 1))),
        "gc_status": draw(st.integers(0, 1)),
        "gba_status": draw(st.integers(0, 1)),
        "charge_status": ChargeStatus(draw(st.integers(-1, 6))),
        "loop_status": draw(I32),
        "power": draw(F32),
        "target_num_id": draw(I32),
        "target_status": TargetStatus(draw(st.integers(-2, 4))),
        "current_pose_x": draw(F32),
        "current_pose_y": draw(F32),
        "current_angle": draw(F32),
    }
    if layout is UDP_V2:
        fields["target_distance"] = draw(F32)
    return GalileoStatus(**fields)


ANY_UDP = st.sampled_from([UDP_V1, UDP_V2]).flatmap(udp_statuses)


@given(ANY_UDP)
def test_round_trip(status: GalileoStatus) -> None:
    frame = encode_status(status)
    assert len(frame) == UDP_LAYOUTS[status.layout].frame_size
    assert UdpStatusDecoder().feed(frame) == [status]


@given(st.lists(ANY_UDP, min_size=1, max_size=5))
def test_round_trip_many_per_datagram(statuses: list[GalileoStatus]) -> None:
    datagram = b"".join(encode_status(status) for status in statuses)
    assert UdpStatusDecoder().feed(datagram) == statuses


@given(st.binary(max_size=200), ANY_UDP)
def test_never_raises_and_a_clean_datagram_still_decodes(
    noise: bytes, status: GalileoStatus
) -> None:
    decoder = UdpStatusDecoder()
    decoder.feed(noise)
    assert decoder.feed(encode_status(status)) == [status]


# --- the robot's command parser (device side, for the simulator) ---------------------------


def _feed(decoder: DatagramCommandDecoder, *hex_datagrams: str) -> list[object]:
    return [decoder.feed(bytes.fromhex(d)) for d in hex_datagrams]


def test_several_commands_per_datagram_run_in_order() -> None:
    datagram = b"".join(HEADER + b"\x02f" + bytes((n,)) for n in range(20))
    assert DatagramCommandDecoder().feed(datagram) == [Forward(n) for n in range(20)]


def test_a_trailing_byte_invalidates_the_frame() -> None:
    assert _feed(DatagramCommandDecoder(), "cdebd7 02 66 0f ff") == [[]]


def test_the_registration_frame_is_valid_and_does_nothing() -> None:
    decoder = DatagramCommandDecoder()
    assert _feed(decoder, "cdebd7 00", "cdebd7 02 67 03") == [[], [Goto(3)]]
    assert decoder.stats.bad_lengths == 0


def test_carry_over_as_measured_on_the_vendor_service() -> None:
    # docs/protocol.md §7.5: the stale partial frame survives later whole frames and, with a
    # stray byte, becomes a phantom f 20.
    out = _feed(
        DatagramCommandDecoder(),
        "cdebd7 02 66", "cdebd7 02 66 29", "cdebd7 02 66 2a", "cdebd7 02 66 2b", "14",
    )  # fmt: skip
    assert out == [[], [Forward(41)], [Forward(42)], [Forward(43)], [Forward(20)]]


def test_a_split_frame_is_completed_and_a_bare_header_clears_the_carry() -> None:
    assert _feed(DatagramCommandDecoder(), "cdeb", "d7 02 67 03") == [[], [Goto(3)]]
    assert _feed(DatagramCommandDecoder(), "cdebd7 02 66", "cdebd7", "14") == [[], [], []]
