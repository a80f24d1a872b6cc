"""Status model and wire enums shared by every layer (PROTOCOL.md §1)."""

from __future__ import annotations

import enum
import math
from collections.abc import Callable, Mapping, Sequence
from typing import Any

from pydantic import BaseModel, ConfigDict

__all__ = [
    "ARRIVED_DISTANCE",
    "STATUS_FIELDS",
    "AngleGoalStatus",
    "ChargeStatus",
    "GalileoStatus",
    "MapStatus",
    "NavStatus",
    "Pose",
    "StatusLayout",
    "TargetStatus",
    "VisualStatus",
]

#: ``abs(target_distance)`` below this means "arrived" (PROTOCOL.md §1, field 11).
ARRIVED_DISTANCE = 0.01

#: What the vendor's serial node sends, with a counting time_stamp, until the navigation
#: system's first status reaches it, and again after it restarts: its constructor's
#: defaults (PROTOCOL.md §1). The robot's own status never has all of them at once: its
#: pose is -1 when unknown and its supply voltage is not 0.
_PLACEHOLDER: dict[str, float] = {
    "nav_status": 0, "visual_status": 0, "map_status": 0, "gc_status": 0, "gba_status": 0,
    "charge_status": 0, "loop_status": 0, "power": 0.0, "target_num_id": -1,
    "target_status": -1, "target_distance": -1.0, "angle_goal_status": -1,
    "control_speed_x": 0.0, "control_speed_theta": 0.0, "current_speed_x": 0.0,
    "current_speed_theta": 0.0, "current_pose_x": 0.0, "current_pose_y": 0.0,
    "current_angle": 0.0, "busy_status": 0,
}  # fmt: skip


class _TolerantIntEnum(enum.IntEnum):
    """IntEnum that turns an unknown wire value into a pseudo-member instead of raising."""

    @classmethod
    def _missing_(cls, value: object) -> Any:
        if not isinstance(value, int) or isinstance(value, bool):
            return None
        # Not cached in the value map: bit-flipped garbage must not grow memory.
        member = int.__new__(cls, value)
        member._name_ = f"UNKNOWN_{value}"
        member._value_ = value
        return member

    @property
    def known(self) -> bool:
        """True when the value is one the protocol document names."""
        return self._name_ is not None and not self._name_.startswith("UNKNOWN_")


class NavStatus(_TolerantIntEnum):
    """Navigation service state (field ``nav_status``)."""

    CLOSED = 0  # 导航服务关闭
    OPEN = 1  # 导航服务开启


class VisualStatus(_TolerantIntEnum):
    """Visual SLAM state (field ``visual_status``); TRACKING and LOST both mean initialised."""

    OFF = -1  # 视觉系统未开启
    NOT_INITIALISED = 0  # 未初始化
    TRACKING = 1  # 正常跟踪
    LOST = 2  # 跟踪丢失


class MapStatus(_TolerantIntEnum):
    """Map-building state (field ``map_status``)."""

    IDLE = 0  # 未建图
    MAPPING = 1  # 正在建图


class ChargeStatus(_TolerantIntEnum):
    """Charging state (field ``charge_status``)."""

    FREE = 0  # 未充电
    CHARGING = 1  # 充电中
    CHARGED = 2  # 充满 (涓流)
    FINDING_DOCK = 3  # 寻找充电桩
    DOCKING = 4  # 对接中
    ERROR = 5  # 错误


class TargetStatus(_TolerantIntEnum):
    """Goal state (field ``target_status``); real firmware reports errors as INVALID (-1)."""

    INVALID = -1  # 无效 (固件也用它表示错误)
    FREE = 0  # 空闲: 到达或取消
    WORKING = 1  # 正在前往目标
    PAUSED = 2  # 暂停
    ERROR = 3  # 错误 (文档)


class AngleGoalStatus(_TolerantIntEnum):
    """Rotate-to-angle result (field ``angle_goal_status``)."""

    INVALID = -1
    NOT_DONE = 0
    DONE = 1
    ERROR = 2


class StatusLayout(str, enum.Enum):
    """Wire layout a status frame was decoded from (PROTOCOL.md §1)."""

    V1 = "v1"
    V1_CHARGE = "v1_charge"
    V2_TRUNCATED = "v2_truncated"
    V2 = "v2"
    ROS = "ros"

    def __str__(self) -> str:
        return self.value


class Pose(BaseModel):
    """Robot pose in the ``map`` frame: metres and radians."""

    model_config = ConfigDict(frozen=True)

    x: float
    y: float
    theta: float

    @property
    def degrees(self) -> float:
        """Heading in degrees."""
        return math.degrees(self.theta)


class GalileoStatus(BaseModel):
    """One decoded status frame; fields its layout lacks are None, never zero."""

    model_config = ConfigDict(frozen=True)

    layout: StatusLayout = StatusLayout.V2
    nav_status: NavStatus | None = None
    visual_status: VisualStatus | None = None
    map_status: MapStatus | None = None
    gc_status: int | None = None
    gba_status: int | None = None
    charge_status: ChargeStatus | None = None
    loop_status: int | None = None
    power: float | None = None
    target_num_id: int | None = None
    target_status: TargetStatus | None = None
    target_distance: float | None = None
    angle_goal_status: AngleGoalStatus | None = None
    control_speed_x: float | None = None
    control_speed_theta: float | None = None
    current_speed_x: float | None = None
    current_speed_theta: float | None = None
    time_stamp: int | None = None
    current_pose_x: float | None = None
    current_pose_y: float | None = None
    current_angle: float | None = None
    busy_status: int | None = None

    @property
    def navigating(self) -> bool:
        """Navigation service open."""
        return self.nav_status == NavStatus.OPEN

    @property
    def visual_initialised(self) -> bool:
        """Visual SLAM initialised (tracking or lost)."""
        return self.visual_status in (VisualStatus.TRACKING, VisualStatus.LOST)

    @property
    def is_busy(self) -> bool:
        """Robot busy: commands are queued until it is not."""
        return self.busy_status == 1

    @property
    def mapping(self) -> bool:
        """Map building running (None-safe: False when the layout lacks the field)."""
        return self.map_status == MapStatus.MAPPING

    @property
    def patrolling(self) -> bool:
        """Auto-patrol running."""
        return self.loop_status == 1

    @property
    def charging(self) -> bool:
        """On the dock and charging (or trickle-charged)."""
        return self.charge_status in (ChargeStatus.CHARGING, ChargeStatus.CHARGED)

    @property
    def goal_active(self) -> bool:
        """A goal is working or paused."""
        return self.target_status in (TargetStatus.WORKING, TargetStatus.PAUSED)

    @property
    def goal_failed(self) -> bool:
        """The goal state is an error (3 in the document, -1 on real firmware)."""
        return self.target_status in (TargetStatus.ERROR, TargetStatus.INVALID)

    @property
    def arrived(self) -> bool:
        """Goal free and within ARRIVED_DISTANCE of its target."""
        return (
            self.target_status == TargetStatus.FREE
            and self.target_distance is not None
            and abs(self.target_distance) < ARRIVED_DISTANCE
        )

    @property
    def is_placeholder(self) -> bool:
        """The vendor serial node's start-up defaults, not the robot's status (PROTOCOL.md §1)."""
        if self.power != 0.0:
            return False
        for name, default in _PLACEHOLDER.items():
            value = getattr(self, name)
            if value is not None and value != default:
                return False
        return True

    @property
    def pose(self) -> Pose | None:
        """Pose in the map frame, or None when the layout lacks it or it is unknown (-1)."""
        x, y, theta = self.current_pose_x, self.current_pose_y, self.current_angle
        if x is None or y is None or theta is None:
            return None
        if x == -1.0 and y == -1.0 and theta == -1.0:
            return None
        return Pose(x=x, y=y, theta=theta)

    @classmethod
    def trusted(cls, values: dict[str, Any]) -> GalileoStatus:
        """Build from already-typed decoder values without validation; adopts ``values``.

        Keys must be field names; missing fields take their defaults. When every field is
        given the dict becomes the instance's storage, so the caller must not reuse it.
        """
        status = _new_status(cls)
        fields_set: set[str]
        if len(values) == _FIELD_COUNT:  # every field given (the keys are field names)
            fields_set = _ALL_FIELDS  # shared and read-only: no set built per frame
        else:
            fields_set = set(values)
            values = {**_FIELD_DEFAULTS, **values}
        # What model_construct sets, without its per-field alias and default handling
        # (about 8x faster; the decoder calls this 30 times a second per robot).
        _set(status, "__dict__", values)
        _set_fields_set(status, fields_set)
        _set_extra(status, None)
        _set_private(status, None)
        return status

    @classmethod
    def builder(
        cls,
        layout: StatusLayout,
        fields: Sequence[str],
        maps: Mapping[str, Mapping[int, Any]],
    ) -> Callable[[tuple[Any, ...]], GalileoStatus]:
        """A function: raw values named ``fields`` in order → status, like ``trusted``.

        A field in ``maps`` is looked up there (an enum map); the others are taken as they
        are, so the caller guarantees the types. Fields not in ``fields`` keep defaults.
        """
        names = tuple(fields)
        unknown = set(names) - _FIELD_DEFAULTS.keys()
        if unknown or "layout" in names or len(set(names)) != len(names):
            raise ValueError(f"not distinct status fields: {names}")
        namespace: dict[str, Any] = {
            "new": _new_status, "cls": cls, "set_dict": _set_dict,
            "set_fields_set": _set_fields_set, "set_extra": _set_extra,
            "set_private": _set_private, "Compact": _Compact, "layout": layout,
            "fields_set": _ALL_FIELDS if len(names) + 1 == _FIELD_COUNT
            else _SharedFieldsSet((*names, "layout")),
        }  # fmt: skip
        exec(_builder_source(names, maps, namespace, fast=False), namespace)
        namespace["build_any"] = namespace["build"]
        exec(_builder_source(names, maps, namespace, fast=True), namespace)
        build: Callable[[tuple[Any, ...]], GalileoStatus] = namespace["build"]
        return build


def _builder_source(
    names: tuple[str, ...],
    maps: Mapping[str, Mapping[int, Any]],
    namespace: dict[str, Any],
    *,
    fast: bool,
) -> str:
    """Source of ``build(values)`` for GalileoStatus.builder (names of ``namespace``).

    Generated like dataclasses' __init__. The fields are stored as attributes of a
    ``_Compact`` instance, always in the model's order, and its ``__dict__`` becomes the
    status's: CPython stores such attributes with specialised instructions, and their dict
    shares one key table. ``fast`` looks enum values up in exact dicts, whose lookup CPython
    also specialises, and falls back to ``build_any`` (the maps themselves, which make
    pseudo-members of unknown values) on a value they lack.
    """
    local = {name: f"v{index}" for index, name in enumerate(names)}
    lines = ["def build(values):"]
    if names:
        lines.append(f"    {', '.join(local.values())}, = values")
    mapped = [name for name in names if name in maps]
    if fast and mapped:
        lines.append("    try:")
        for name in mapped:
            namespace[f"known_{name}"] = dict(maps[name])
            lines.append(f"        e_{name} = known_{name}[{local[name]}]")
        lines += ["    except KeyError:", "        return build_any(values)"]
    lines.append("    fields = Compact()")  # a plain call: object.__new__ parses its arguments
    for name in _FIELD_DEFAULTS:  # "layout" among them
        if name == "layout":
            value = "layout"
        elif name in maps and name in local:
            if fast:
                value = f"e_{name}"
            else:
                namespace[f"map_{name}"] = maps[name]
                value = f"map_{name}[{local[name]}]"
        elif name in local:
            value = local[name]
        else:
            namespace[f"default_{name}"] = _FIELD_DEFAULTS[name]
            value = f"default_{name}"
        lines.append(f"    fields.{name} = {value}")
    lines += [
        "    status = new(cls)",
        "    set_dict(status, fields.__dict__)",
        "    set_fields_set(status, fields_set)",
        "    set_extra(status, None)",
        "    set_private(status, None)",
        "    return status",
    ]
    return "\n".join(lines) + "\n"


class _Compact:
    """Holds a status's fields as attributes; its instances' dicts share one key table.

    CPython's split dicts: a 22-field status dict then takes about 250 bytes instead of
    830, less to allocate and less memory to touch when a robot's previous status is
    freed 30 times a second, which counts across a large fleet (BENCHMARKS.md §2).
    """


_new_status = object.__new__
_set = object.__setattr__
_set_dict = vars(BaseModel)["__dict__"].__set__
# BaseModel keeps these in __slots__: their descriptors set them a little faster.
_set_fields_set = vars(BaseModel)["__pydantic_fields_set__"].__set__
_set_extra = vars(BaseModel)["__pydantic_extra__"].__set__
_set_private = vars(BaseModel)["__pydantic_private__"].__set__
_FIELD_DEFAULTS: dict[str, Any] = {
    name: field.default for name, field in GalileoStatus.model_fields.items()
}
_FIELD_COUNT = len(_FIELD_DEFAULTS)


class _SharedFieldsSet(set[str]):
    """``model_fields_set`` of every fully-given trusted status: one read-only set.

    Copies (``copy``, ``model_copy``, ``deepcopy``, pickling) are plain sets, so pydantic's
    own updates of a copy work; changing the shared set itself raises TypeError.
    """

    __slots__ = ()

    def _read_only(self, *args: object, **kwargs: object) -> Any:
        raise TypeError("this fields set is shared by trusted statuses: change a copy")

    add = discard = remove = pop = clear = update = _read_only
    difference_update = intersection_update = symmetric_difference_update = _read_only
    __ior__ = __iand__ = __isub__ = __ixor__ = _read_only

    def __copy__(self) -> set[str]:
        return set(self)

    def __deepcopy__(self, memo: dict[int, Any]) -> set[str]:
        return set(self)

    def __reduce__(self) -> tuple[Any, ...]:
        return (set, (list(self),))


_ALL_FIELDS = _SharedFieldsSet(_FIELD_DEFAULTS)

#: Names of the wire fields, in the order of the current (v2) struct.
STATUS_FIELDS: tuple[str, ...] = tuple(n for n in GalileoStatus.model_fields if n != "layout")
