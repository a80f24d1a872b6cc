"""GalileoStatus, its enums and convenience properties (docs/protocol.md §1)."""

from __future__ import annotations

import copy
import math
import pickle
import struct
from typing import Any

import pydantic
import pytest

from galileo_async.models import (
    STATUS_FIELDS,
    AngleGoalStatus,
    ChargeStatus,
    GalileoStatus,
    MapStatus,
    NavStatus,
    Pose,
    StatusLayout,
    TargetStatus,
    VisualStatus,
)
from galileo_async.protocol import HEADER, StatusDecoder, encode_status
from galileo_async.protocol._build import status_builder, trusted_status
from tests.support import vectors as v

ENUMS = [NavStatus, VisualStatus, MapStatus, ChargeStatus, TargetStatus, AngleGoalStatus]


def test_field_order_is_the_v2_struct_order() -> None:
    assert STATUS_FIELDS == v.V2_NAMES
    assert tuple(GalileoStatus.model_fields) == ("layout", *STATUS_FIELDS)


def test_wire_values_of_the_enums() -> None:
    assert [int(m) for m in NavStatus] == [0, 1]
    assert [int(m) for m in VisualStatus] == [-1, 0, 1, 2]
    assert [int(m) for m in MapStatus] == [0, 1]
    assert [int(m) for m in ChargeStatus] == [0, 1, 2, 3, 4, 5]
    assert [int(m) for m in TargetStatus] == [-1, 0, 1, 2, 3]
    assert [int(m) for m in AngleGoalStatus] == [-1, 0, 1, 2]
    assert [str(m) for m in StatusLayout] == [
        "v1", "v1_charge", "v2_truncated", "v2", "ros", "udp_v1", "udp_v2",
    ]  # fmt: skip


def test_defaults_are_unknown_not_zero() -> None:
    status = GalileoStatus()
    assert status.layout is StatusLayout.V2
    assert all(getattr(status, name) is None for name in STATUS_FIELDS)
    assert v.V1_STATUS.charge_status is None
    assert v.V1_CHARGE_STATUS.time_stamp is None
    assert v.V2_TRUNCATED_STATUS_A.control_speed_x is None


@pytest.mark.parametrize("enum_type", ENUMS)
def test_unknown_value_becomes_a_pseudo_member(enum_type: type[Any]) -> None:
    member = enum_type(7)
    assert int(member) == 7
    assert member == 7
    assert isinstance(member, enum_type)
    assert member.known is False
    assert "7" in repr(member)
    assert all(m.known for m in enum_type)
    assert 7 not in enum_type._value2member_map_  # garbage does not grow the enum


def test_unknown_values_pass_model_validation() -> None:
    status = GalileoStatus(nav_status=7, visual_status=-5, charge_status=99, target_status=3)
    assert status.nav_status is not None
    assert status.visual_status is not None
    assert (int(status.nav_status), status.nav_status.known) == (7, False)
    assert (int(status.visual_status), status.visual_status.known) == (-5, False)
    assert status.target_status is TargetStatus.ERROR
    assert status == GalileoStatus(
        nav_status=7, visual_status=-5, charge_status=99, target_status=3
    )
    with pytest.raises(pydantic.ValidationError):
        GalileoStatus(nav_status="open")


def test_status_is_frozen() -> None:
    status = v.V2_ACTIVE_STATUS
    with pytest.raises(pydantic.ValidationError):
        status.nav_status = NavStatus.CLOSED  # type: ignore[misc]
    pose = Pose(x=1.0, y=2.0, theta=0.0)
    with pytest.raises(pydantic.ValidationError):
        pose.x = 3.0  # type: ignore[misc]
    assert hash(pose) == hash(Pose(x=1.0, y=2.0, theta=0.0))


def test_trusted_equals_validated() -> None:
    values = v.V2_ACTIVE_STATUS.model_dump()
    assert trusted_status(values) == GalileoStatus(**values)


def test_builder_equals_validated_and_behaves_like_any_status() -> None:
    expected = v.V2_ACTIVE_STATUS
    names = list(STATUS_FIELDS)
    maps = {"nav_status": {1: NavStatus.OPEN}, "target_status": {1: TargetStatus.WORKING}}
    build = status_builder(StatusLayout.V2, names, maps)
    raw = tuple(int(getattr(expected, name)) if name in maps else getattr(expected, name)
                for name in names)  # fmt: skip
    built = build(raw)
    assert built == expected
    assert repr(built) == repr(expected)
    assert built.model_fields_set == set(GalileoStatus.model_fields)
    assert built.model_dump() == expected.model_dump()
    assert copy.deepcopy(built) == pickle.loads(pickle.dumps(built)) == expected
    assert built.model_copy(update={"power": 1.0}).power == 1.0
    again = build(raw)
    assert again == built
    assert again is not built
    assert type(built) is GalileoStatus
    with pytest.raises(pydantic.ValidationError):
        built.power = 2.0  # type: ignore[misc]
    assert not hasattr(built, "__dict__")  # a slotted record: no dict per status


def test_builder_falls_back_to_the_maps_for_values_they_only_make_on_demand() -> None:
    class OnDemand(dict[int, Any]):
        def __missing__(self, raw: int) -> Any:
            return NavStatus(raw)

    build = status_builder(
        StatusLayout.V1, ["nav_status", "power"], {"nav_status": OnDemand({1: NavStatus.OPEN})}
    )
    assert build((1, 12.5)).nav_status is NavStatus.OPEN
    unknown = build((9, 12.5)).nav_status  # not in the map: made by __missing__
    assert int(unknown) == 9
    assert unknown.known is False
    assert build((1, 13.0)).nav_status is NavStatus.OPEN  # nothing cached from the miss


def test_builder_for_a_layout_with_fewer_fields() -> None:
    build = status_builder(StatusLayout.V1, ["nav_status", "power"], {})
    built = build((1, 12.5))
    assert built == GalileoStatus(layout=StatusLayout.V1, nav_status=1, power=12.5)
    assert built.model_fields_set == {"layout", "nav_status", "power"}
    assert built.time_stamp is None


@pytest.mark.parametrize("fields", [["layout"], ["power", "power"], ["no_such_field"]])
def test_builder_refuses_fields_that_are_not_distinct_status_fields(fields: list[str]) -> None:
    with pytest.raises(ValueError, match="not distinct status fields"):
        status_builder(StatusLayout.V2, fields, {})


def status(**fields: Any) -> GalileoStatus:
    return GalileoStatus(**fields)


@pytest.mark.parametrize(
    ("fields", "expected"),
    [
        ({"visual_status": 1}, True),
        ({"visual_status": 2}, True),  # lost still means initialised
        ({"visual_status": 0}, False),
        ({"visual_status": -1}, False),
        ({"visual_status": 9}, False),
        ({}, False),
    ],
)
def test_visual_initialised(fields: dict[str, int], expected: bool) -> None:
    assert status(**fields).visual_initialised is expected


@pytest.mark.parametrize(
    ("name", "prop", "true_values", "false_values"),
    [
        ("busy_status", "is_busy", [1], [0, 2, None]),
        ("nav_status", "navigating", [1], [0, 7, None]),
        ("map_status", "mapping", [1], [0, None]),
        ("loop_status", "patrolling", [1], [0, None]),
        ("charge_status", "charging", [1, 2], [0, 3, 4, 5, None]),
        ("target_status", "goal_active", [1, 2], [-1, 0, 3, None]),
        ("target_status", "goal_failed", [3, -1], [0, 1, 2, None]),
    ],
)
def test_flag_properties(
    name: str, prop: str, true_values: list[int], false_values: list[int | None]
) -> None:
    for value in true_values:
        assert getattr(status(**{name: value}), prop) is True, (name, value)
    for other in false_values:
        assert getattr(status(**{name: other}), prop) is False, (name, other)


def test_pose() -> None:
    pose = status(current_pose_x=1.5, current_pose_y=-2.0, current_angle=math.pi / 2).pose
    assert pose == Pose(x=1.5, y=-2.0, theta=math.pi / 2)
    assert pose is not None
    assert pose.degrees == pytest.approx(90.0)
    assert v.V2_ACTIVE_STATUS.pose == Pose(x=1.5, y=-2.75, theta=0.5)
    assert status(current_pose_x=-1.0, current_pose_y=-1.0, current_angle=-1.0).pose is None
    assert status(current_pose_x=-1.0, current_pose_y=-1.0, current_angle=0.0).pose is not None
    assert status(current_pose_x=0.0, current_pose_y=0.0).pose is None  # angle missing
    for old in (v.V1_STATUS, v.V1_CHARGE_STATUS, v.V2_TRUNCATED_STATUS_A):
        assert old.pose is None  # layouts without a pose


def test_unknown_enum_values_decode_to_pseudo_members() -> None:
    values = list(v.V2_ACTIVE_VALUES)
    values[0], values[1], values[5], values[9], values[11] = 7, -9, 42, -7, 2**31 - 1
    frame = HEADER + b"\x55" + struct.pack(v.V2_FORMAT, *values) + b"\x00"
    decoder = StatusDecoder()
    (status,) = decoder.feed(frame)
    for name, raw in [
        ("nav_status", 7),
        ("visual_status", -9),
        ("charge_status", 42),
        ("target_status", -7),
        ("angle_goal_status", 2**31 - 1),
    ]:
        member = getattr(status, name)
        assert int(member) == raw
        assert member == raw
        assert member.known is False
        assert isinstance(member, type(getattr(v.V2_ACTIVE_STATUS, name)))
    assert status.nav_status is not None
    assert isinstance(status.nav_status, NavStatus)
    assert status.map_status is not None
    assert status.map_status.known is True
    assert encode_status(status) == frame
    assert status.target_status != TargetStatus.INVALID


def test_the_pydantic_style_api_of_the_record() -> None:
    status = v.V2_ACTIVE_STATUS
    assert not isinstance(status, pydantic.BaseModel)
    assert GalileoStatus.model_validate(status) is status
    assert GalileoStatus.model_validate(dict(status)) == status
    assert GalileoStatus.model_validate_json(status.model_dump_json()) == status
    assert GalileoStatus.model_json_schema()["title"] == "GalileoStatus"
    assert set(GalileoStatus.model_json_schema()["properties"]) == set(GalileoStatus.model_fields)
    assert str(status) == repr(status)[len("GalileoStatus(") : -1].replace(", ", " ")
    assert GalileoStatus(nav_status=1, no_such_field=3) == GalileoStatus(nav_status=1)  # ignored
    assert GalileoStatus(nav_status=1).model_fields_set == {"nav_status"}
    copied = GalileoStatus(nav_status=1).model_copy(update={"power": 12.5})
    assert copied.model_fields_set == {"nav_status", "power"}
    assert copied.model_dump(exclude_unset=True) == {"nav_status": NavStatus.OPEN, "power": 12.5}
    with pytest.raises(ValueError, match="no_such_field"):
        status.model_copy(update={"no_such_field": 1})
    with pytest.raises(pydantic.ValidationError, match="frozen"):
        del status.power
    with pytest.raises(pydantic.ValidationError, match="1 validation error for GalileoStatus"):
        GalileoStatus.model_validate({"power": "lots"})


def test_a_status_is_a_field_type_of_pydantic_models() -> None:
    class Report(pydantic.BaseModel):
        status: GalileoStatus
        previous: GalileoStatus | None = None

    report = Report(status=v.V2_ACTIVE_STATUS)
    assert report.status == v.V2_ACTIVE_STATUS
    assert type(report.status) is GalileoStatus
    assert report.model_dump()["status"] == v.V2_ACTIVE_STATUS.model_dump()
    again = Report.model_validate_json(report.model_dump_json())
    assert again == report
    assert type(again.status) is GalileoStatus
    assert Report(status={"nav_status": 1}).status == GalileoStatus(nav_status=1)
    with pytest.raises(pydantic.ValidationError, match=r"status\.nav_status"):
        Report(status={"nav_status": "open"})
    assert Report.model_json_schema()["properties"]["status"] == {"$ref": "#/$defs/GalileoStatus"}
