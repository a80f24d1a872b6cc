"""ROS message definitions, md5 sums and (de)serialisation, checked against genpy."""

from __future__ import annotations

import json
import struct
from typing import Any

import pytest

from galileo_async.models import (
    ChargeStatus,
    NavStatus,
    StatusLayout,
    TargetStatus,
    VisualStatus,
)
from galileo_async.protocol.commands import (
    AddTarget,
    Cancel,
    Goto,
    RawCommand,
    SetPatrolDwell,
    StartNavigation,
    StopPatrol,
)
from galileo_async.ros import messages as m
from galileo_async.ros.msgdef import (
    MessageDefinitionError,
    compile_decoder,
    md5sum,
    parse_full_definition,
    parse_msg,
)
from tests.support.ros_support import genpy_script

POINT_TYPE = "galileo_test/Point"
MIXED_TYPE = "galileo_test/Mixed"
MIXED_TEXT = """# a comment line
int32 ANSWER = 42
string GREETING= hello # this is part of the value
Header header
uint8[] raw
float64[3] triple
time t
duration d
string name
Point[] points
galileo_test/Point single
bool flag
int64 big
char c
byte b
"""
MIXED_FULL = (
    MIXED_TEXT
    + "\n"
    + "=" * 80
    + "\nMSG: std_msgs/Header\n"
    + m.HEADER_DEFINITION
    + "\n"
    + "=" * 80
    + f"\nMSG: {POINT_TYPE}\nfloat32 x  # metres\nfloat32 y\n"
)

COMMANDS = [
    StartNavigation(),
    Goto(7),
    Cancel(),
    StopPatrol(),
    SetPatrolDwell(30),
    AddTarget(1.25, -3.5),
    RawCommand(b"\xaa\x44"),
]

STATUS_VALUES: dict[str, Any] = {
    "navStatus": 1,
    "visualStatus": 2,
    "mapStatus": 0,
    "gcStatus": 1,
    "gbaStatus": 0,
    "chargeStatus": 4,
    "loopStatus": 1,
    "power": 24.5,
    "targetNumID": 3,
    "targetStatus": 1,
    "targetDistance": 2.25,
    "angleGoalStatus": 0,
    "controlSpeedX": 0.5,
    "controlSpeedTheta": -0.25,
    "currentSpeedX": 0.375,
    "currentSpeedTheta": 0.125,
    "currentPosX": 1.5,
    "currentPosY": -2.5,
    "currentAngle": 3.0,
    "busyStatus": 1,
}

GENPY_SCRIPT = r"""
import json, sys
import genpy, genpy.dynamic
job = json.load(sys.stdin)
out = {"md5": {}, "cmds": [], "status": {}, "mixed": None}
classes = {}
for name, text in job["defs"].items():
    core = name.split("#")[0]
    cls = genpy.dynamic.generate_dynamic(core, text)[core]
    classes[name] = (cls, genpy.dynamic.generate_dynamic(core, text))
    out["md5"][name] = cls._md5sum
def ser(msg):
    import io
    buf = io.BytesIO(); msg.serialize(buf); return buf.getvalue().hex()
cmds_cls = classes["galileo_serial_server/GalileoNativeCmds"][0]
for seq, secs, nsecs, payload in job["cmds"]:
    msg = cmds_cls()
    msg.header.seq = seq; msg.header.stamp = genpy.Time(secs, nsecs); msg.header.frame_id = ""
    data = bytes.fromhex(payload); msg.length = len(data); msg.data = data
    out["cmds"].append(ser(msg))
for name in ("galileo_serial_server/GalileoStatus", "galileo_serial_server/GalileoStatus#13"):
    cls = classes[name][0]
    msg = cls(); msg.header.seq = 77; msg.header.frame_id = "map"
    for key, value in job["status"].items():
        if key in cls.__slots__:
            setattr(msg, key, value)
    out["status"][name] = ser(msg)
mixed_cls, mixed_all = classes["galileo_test/Mixed"]
point = mixed_all["galileo_test/Point"]
msg = mixed_cls(raw=b"\x01\x02", triple=[1.5, 2.5, 3.5], t=genpy.Time(5, 6),
                d=genpy.Duration(-1, 7), name="h\u00e9llo", points=[point(1, 2), point(3, 4)],
                single=point(5, 6), flag=True, big=-2**40, c=200, b=-3)
msg.header.seq = 9
out["mixed"] = ser(msg)
print(json.dumps(out))
"""


@pytest.fixture(scope="module")
def genpy_results() -> dict[str, Any]:
    """md5 sums and serialised messages computed by genpy under the system Python."""
    job = {
        "defs": {
            m.CMDS_TYPE: m.full_definition(m.CMDS_DEFINITION),
            m.STATUS_TYPE: m.full_definition(m.STATUS_DEFINITION),
            m.STATUS_TYPE + "#13": m.full_definition(m.STATUS_DEFINITION_13),
            MIXED_TYPE: MIXED_FULL,
        },
        "cmds": [
            [i + 1, 1_700_000_000 + i, 250_000_000, c.payload().hex()]
            for i, c in enumerate(COMMANDS)
        ],
        "status": STATUS_VALUES,
    }
    result: dict[str, Any] = json.loads(genpy_script(GENPY_SCRIPT, json.dumps(job)))
    return result


def test_md5_sums_match_genpy(genpy_results: dict[str, Any]) -> None:
    md5 = genpy_results["md5"]
    assert md5[m.CMDS_TYPE] == m.CMDS_MD5
    assert md5[m.STATUS_TYPE] == m.STATUS_MD5
    short = parse_full_definition(m.STATUS_TYPE, m.full_definition(m.STATUS_DEFINITION_13))
    assert md5sum(m.STATUS_TYPE, short) == md5[m.STATUS_TYPE + "#13"]
    mixed = parse_full_definition(MIXED_TYPE, MIXED_FULL)
    assert md5sum(MIXED_TYPE, mixed) == md5[MIXED_TYPE]


def test_cmds_serialisation_matches_genpy(genpy_results: dict[str, Any]) -> None:
    for i, (command, expected) in enumerate(zip(COMMANDS, genpy_results["cmds"], strict=True)):
        data = m.encode_cmds(command, seq=i + 1, stamp=1_700_000_000 + i + 0.25)
        assert data.hex() == expected, command


def test_start_navigation_cmds_layout() -> None:
    data = m.encode_cmds(StartNavigation(), seq=1, stamp=0.0)
    # header (seq, secs, nsecs, empty frame_id), length 2, data [0x6d, 0] (docs/protocol.md §3)
    assert data == struct.pack("<IIII", 1, 0, 0, 0) + struct.pack("<II", 2, 2) + b"m\x00"


def test_decodes_the_final_status_by_field_names(genpy_results: dict[str, Any]) -> None:
    data = bytes.fromhex(genpy_results["status"][m.STATUS_TYPE])
    decoder = m.StatusMessageDecoder(m.full_definition(m.STATUS_DEFINITION))
    status = decoder.decode(data)
    assert decoder.md5 == m.STATUS_MD5
    assert status.layout == StatusLayout.ROS
    assert status.time_stamp == 77  # from header.seq
    assert status.nav_status is NavStatus.OPEN
    assert status.visual_status is VisualStatus.LOST
    assert status.charge_status is ChargeStatus.DOCKING
    assert status.target_status is TargetStatus.WORKING
    assert status.target_num_id == 3
    assert status.busy_status == 1
    assert status.gc_status == 1
    assert (status.current_pose_x, status.current_pose_y) == (1.5, -2.5)
    assert status.current_angle == 3.0
    assert status.power == 24.5
    assert status.control_speed_theta == -0.25


def test_decodes_the_13_field_status_with_missing_fields_none(
    genpy_results: dict[str, Any],
) -> None:
    data = bytes.fromhex(genpy_results["status"][m.STATUS_TYPE + "#13"])
    status = m.StatusMessageDecoder(m.full_definition(m.STATUS_DEFINITION_13)).decode(data)
    assert status.charge_status is ChargeStatus.DOCKING
    assert status.target_distance == 2.25
    assert status.current_speed_theta == 0.125
    for missing in ("map_status", "gc_status", "gba_status", "busy_status", "current_pose_x"):
        assert getattr(status, missing) is None, missing
    assert status.pose is None


def test_decoder_follows_the_definition_not_a_fixed_order() -> None:
    text = "Header header\nfloat32 power\nint32 targetNumID\nint32 somethingNew\nint32 navStatus\n"
    decoder = m.StatusMessageDecoder(m.full_definition(text))
    data = struct.pack("<IIII", 5, 0, 0, 0) + struct.pack("<fiii", 11.5, 4, 99, 1)
    status = decoder.decode(data)
    assert status.power == 11.5
    assert status.target_num_id == 4
    assert status.nav_status is NavStatus.OPEN
    assert status.visual_status is None
    assert status.time_stamp == 5


def test_decoder_without_definition_uses_a_known_md5() -> None:
    decoder = m.StatusMessageDecoder(None, m.STATUS_MD5)
    assert len(decoder.field_names) == 21
    with pytest.raises(MessageDefinitionError):
        m.StatusMessageDecoder("", "0" * 32)


def test_unknown_enum_values_degrade() -> None:
    text = "Header header\nint32 targetStatus\n"
    data = struct.pack("<IIIIi", 1, 0, 0, 0, 42)
    status = m.StatusMessageDecoder(m.full_definition(text)).decode(data)
    assert status.target_status is not None
    assert int(status.target_status) == 42
    assert not status.target_status.known


def test_truncated_status_raises_definition_error() -> None:
    decoder = m.StatusMessageDecoder(m.full_definition(m.STATUS_DEFINITION))
    full = struct.pack("<IIII", 1, 0, 0, 0) + bytes(80)
    decoder.decode(full)
    for cut in (0, 3, 15, 40, len(full) - 1):
        with pytest.raises(MessageDefinitionError):
            decoder.decode(full[:cut])
    with pytest.raises(MessageDefinitionError):  # a frame_id longer than the message
        decoder.decode(struct.pack("<IIII", 1, 0, 0, 1000) + bytes(80))


def test_mixed_message_decodes_like_genpy(genpy_results: dict[str, Any]) -> None:
    specs = parse_full_definition(MIXED_TYPE, MIXED_FULL)
    value = compile_decoder(MIXED_TYPE, specs)(bytes.fromhex(genpy_results["mixed"]))
    assert value["header"] == {"seq": 9, "stamp": (0, 0), "frame_id": ""}
    assert value["raw"] == b"\x01\x02"
    assert value["triple"] == [1.5, 2.5, 3.5]
    assert value["t"] == (5, 6)
    assert value["d"] == (-1, 7)
    assert value["name"] == "h\u00e9llo"
    assert value["points"] == [{"x": 1.0, "y": 2.0}, {"x": 3.0, "y": 4.0}]
    assert value["single"] == {"x": 5.0, "y": 6.0}
    assert value["flag"] == 1
    assert value["big"] == -(2**40)
    assert value["c"] == 200
    assert value["b"] == -3


def test_parse_msg_constants_and_arrays() -> None:
    spec = parse_msg(MIXED_TYPE, MIXED_TEXT)
    assert spec.constants == (
        "int32 ANSWER=42",
        "string GREETING=hello # this is part of the value",
    )
    by_name = {f.name: f for f in spec.fields}
    assert by_name["header"].base_type == "std_msgs/Header"
    assert by_name["points"].base_type == POINT_TYPE
    assert by_name["points"].type_text == POINT_TYPE + "[]"
    assert by_name["triple"].type_text == "float64[3]"
    with pytest.raises(MessageDefinitionError):
        parse_msg("a/B", "int32\n")
    with pytest.raises(MessageDefinitionError):
        compile_decoder("a/B", {"a/B": parse_msg("a/B", "Missing thing\n")})
    with pytest.raises(MessageDefinitionError):
        parse_full_definition("a/B", "int32 x\n" + "=" * 80 + "\nnot a MSG line\n")


def test_the_twist_message_matches_geometry_msgs() -> None:
    assert m.TWIST_MD5 == "9f195f881246fdfa2798d1d3eebca84a"  # geometry_msgs/Twist's md5sum
    assert struct.unpack("<6d", m.encode_twist(0.3, -0.5)) == (0.3, 0.0, 0.0, 0.0, 0.0, -0.5)
