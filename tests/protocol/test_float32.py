"""float32 fields read as the shortest decimal of their float32 (24.28, not 24.280000686645508)."""

from __future__ import annotations

import copy
import json
import math
import pickle
import struct
import subprocess
import sys
from pathlib import Path

from hypothesis import example, given, settings
from hypothesis import strategies as st

from galileo_async.models import FLOAT32_FIELDS, GalileoStatus, StatusLayout, float32_decimal
from galileo_async.protocol import StatusDecoder, encode_status

#: float32 of 24.28 as a Python float: what a decoder unpacks.
NOISY = struct.unpack("<f", struct.pack("<f", 24.28))[0]
#: A status whose every float32 field has a value float32 cannot hold exactly.
SENT = GalileoStatus(
    nav_status=1, visual_status=1, map_status=0, gc_status=0, gba_status=0, charge_status=0,
    loop_status=0, power=24.28, target_num_id=3, target_status=1, target_distance=0.1,
    angle_goal_status=-1, control_speed_x=0.3, control_speed_theta=-0.7, current_speed_x=0.29,
    current_speed_theta=-0.69, time_stamp=7, current_pose_x=1.1, current_pose_y=-2.2,
    current_angle=3.1, busy_status=0,
)  # fmt: skip


def reference(value: float) -> float:
    """The definition: the first n of 6 to 9 whose ``.{n}g`` decimal has value's float32 bits."""
    bits = struct.pack("<f", value)
    for digits in range(6, 10):
        decimal = float(f"{value:.{digits}g}")
        if struct.pack("<f", decimal) == bits:
            return decimal
    raise AssertionError(f"no decimal of 6 to 9 digits round-trips {value!r}")


def decoded(status: GalileoStatus) -> GalileoStatus:
    (out,) = StatusDecoder(StatusLayout.V2).feed(encode_status(status, StatusLayout.V2))
    return out


def test_the_noise_is_what_a_decoder_unpacks() -> None:
    assert NOISY == 24.280000686645508
    assert float32_decimal(NOISY) == 24.28


@settings(max_examples=2000)
@given(st.integers(min_value=0, max_value=2**32 - 1))
@example(0x00000000)  # 0.0
@example(0x80000000)  # -0.0
@example(0x00000001)  # the smallest subnormal
@example(0x807FFFFF)  # the largest negative subnormal
@example(0x00800000)  # the smallest normal
@example(0x7F7FFFFF)  # the largest finite
@example(0x7F800000)  # inf
@example(0xFF800000)  # -inf
@example(0x7FC00000)  # a quiet NaN
@example(0x7F800001)  # a signalling NaN
@example(0xFFFFFFFF)  # a NaN with every payload bit
@example(0x41C23D71)  # 24.28
def test_every_float32_reads_as_the_reference_decimal(bits: int) -> None:
    pattern = bits.to_bytes(4, "little")
    (value,) = struct.unpack("<f", pattern)
    first, again = float32_decimal(value), float32_decimal(value)  # computed, then cached
    if math.isnan(value):
        assert math.isnan(first)
        assert math.isnan(again)
        return
    assert first == again == reference(value)
    assert struct.pack("<f", first) == pattern  # nothing lost: the same float32 bits
    assert math.copysign(1.0, first) == math.copysign(1.0, value)  # -0.0 stays negative


@given(st.floats(allow_nan=False, allow_infinity=False))
def test_a_double_float32_cannot_hold_is_returned_as_it_is(value: float) -> None:
    try:
        exact = struct.unpack("<f", struct.pack("<f", value))[0] == value
    except OverflowError:
        exact = False
    assert float32_decimal(value) == (reference(value) if exact else value)


def test_decimals_of_common_values() -> None:
    assert float32_decimal(24.28) == 24.28  # already a decimal: no float32
    assert float32_decimal(1e300) == 1e300  # beyond float32's range
    assert float32_decimal(struct.unpack("<f", struct.pack("<f", 0.1))[0]) == 0.1
    assert float32_decimal(struct.unpack("<f", struct.pack("<f", -2.2))[0]) == -2.2
    assert float32_decimal(1.5) == 1.5


def test_a_decoded_status_reads_dumps_and_shows_decimals() -> None:
    status = decoded(SENT)
    for name in FLOAT32_FIELDS:
        assert getattr(status, name) == getattr(SENT, name), name
    assert status.power == 24.28
    assert status.model_dump()["power"] == 24.28
    assert json.loads(status.model_dump_json())["current_pose_y"] == -2.2
    assert "power=24.28," in repr(status)
    assert "24.280000686645508" not in repr(status) + str(status)
    assert dict(status)["current_angle"] == 3.1
    pose = status.pose
    assert pose is not None
    assert (pose.x, pose.y, pose.theta) == (1.1, -2.2, 3.1)
    assert status.time_stamp == 7  # not a float32 field: as it is


def test_the_wire_values_stay_available() -> None:
    frame = encode_status(SENT, StatusLayout.V2)
    ((layout, values),) = StatusDecoder(StatusLayout.V2).feed_raw(frame)
    fields = dict(zip(GalileoStatus.model_fields, (layout, *values), strict=True))
    assert fields["power"] == NOISY  # feed_raw: every bit as unpacked
    status = decoded(SENT)
    assert struct.pack("<f", status.power) == struct.pack("<f", NOISY)  # the same bits


def test_equality_and_hash_follow_what_the_fields_read() -> None:
    status = decoded(SENT)
    assert status == SENT
    assert hash(status) == hash(SENT)
    assert status != SENT.model_copy(update={"power": 24.29})
    assert status != SENT.model_copy(update={"layout": StatusLayout.V1})


def test_copies_and_pickles_read_the_same() -> None:
    status = decoded(SENT)
    for other in (copy.copy(status), copy.deepcopy(status), pickle.loads(pickle.dumps(status))):
        assert other.power == 24.28
        assert other == status
    assert status.model_copy(update={"current_pose_x": 5.0}).current_pose_x == 5.0


def test_zero_none_and_non_finite_values() -> None:
    status = decoded(GalileoStatus(power=-0.0, target_distance=math.inf, current_angle=math.nan))
    assert status.power == 0.0
    assert math.copysign(1.0, status.power) == -1.0
    assert status.target_distance == math.inf
    assert math.isnan(status.current_angle)  # type: ignore[arg-type]
    assert GalileoStatus().power is None


def test_decode_raw_prints_the_decimals(tmp_path: Path) -> None:
    capture = tmp_path / "capture.bin"
    capture.write_bytes(encode_status(SENT, StatusLayout.V2) * 2)
    result = subprocess.run(
        [sys.executable, "-m", "galileo_async", "decode", str(capture), "--raw"],
        capture_output=True, text=True, timeout=60, check=True,
    )  # fmt: skip
    first = json.loads(result.stdout.splitlines()[0])
    assert first["power"] == 24.28
    assert first["current_pose_x"] == 1.1
    assert "24.280000686645508" not in result.stdout


def test_decode_raw_keeps_the_digits_the_rounded_lines_drop(tmp_path: Path) -> None:
    capture = tmp_path / "capture.bin"
    capture.write_bytes(encode_status(SENT.model_copy(update={"current_pose_x": 1.23456})))
    decode = [sys.executable, "-m", "galileo_async", "decode", str(capture)]

    def line(*more: str) -> dict[str, object]:
        result = subprocess.run(
            [*decode, *more], capture_output=True, text=True, timeout=60, check=True
        )
        values: dict[str, object] = json.loads(result.stdout)
        return values

    shown, exact = line(), line("--raw")
    assert (shown["current_pose_x"], exact["current_pose_x"]) == (1.235, 1.23456)
