"""Status model and wire enums shared by every layer (docs/protocol.md §1)."""

from __future__ import annotations

import enum
import math
import struct
from collections.abc import Generator, Iterator
from typing import Any

from pydantic import BaseModel, ConfigDict, field_serializer

__all__ = [
    "FLOAT32_FIELDS",
    "STATUS_FIELDS",
    "AngleGoalStatus",
    "ChargeStatus",
    "GalileoStatus",
    "LinkState",
    "MapStatus",
    "NavStatus",
    "Pose",
    "StatusLayout",
    "TargetStatus",
    "VisualStatus",
    "float32_decimal",
]

#: What the vendor's serial node sends, with a counting time_stamp, until the navigation
#: system's first status reaches it, and again after it restarts: its constructor's
#: defaults (docs/protocol.md §1). The robot's own status never has all of them at once: its
#: pose is -1 when unknown and its supply voltage is not 0.
_PLACEHOLDER: dict[str, float] = {
    "nav_status": 0, "visual_status": 0, "map_status": 0, "gc_status": 0, "gba_status": 0,
    "charge_status": 0, "loop_status": 0, "power": 0.0, "target_num_id": -1,
    "target_status": -1, "target_distance": -1.0, "angle_goal_status": -1,
    "control_speed_x": 0.0, "control_speed_theta": 0.0, "current_speed_x": 0.0,
    "current_speed_theta": 0.0, "current_pose_x": 0.0, "current_pose_y": 0.0,
    "current_angle": 0.0, "busy_status": 0,
}  # fmt: skip


#: The status fields every link carries as float32 (serial and UDP frames, the ROS message,
#: the HTTP API's JSON of it): they read as float32_decimal of the wire value.
FLOAT32_FIELDS: tuple[str, ...] = (
    "power", "target_distance", "control_speed_x", "control_speed_theta", "current_speed_x",
    "current_speed_theta", "current_pose_x", "current_pose_y", "current_angle",
)  # fmt: skip

_F32 = struct.Struct("<f")
#: float32 value → its shortest decimal: an idle robot repeats its values, and a status is
#: read more than once. Emptied when full (a moving robot's values rarely come back), so it
#: never holds more than about 25 kB.
_DECIMALS: dict[float, float] = {}
_DECIMALS_MAX = 256
_FORMATS = (".6g", ".7g", ".8g")


def _shortest(value: float) -> float:
    """float32_decimal without the cache."""
    try:
        bits = _F32.pack(value)
    except OverflowError:  # beyond float32's range: a double, not a float32
        return value
    if _F32.unpack(bits)[0] != value:  # NaN, or a double float32 cannot hold exactly
        return value
    for form in _FORMATS:
        decimal = float(format(value, form))
        if _F32.pack(decimal) == bits:
            return decimal
    return float(format(value, ".9g"))  # 9 significant digits always round-trip in float32


def float32_decimal(value: float) -> float:
    """The shortest decimal (6 to 9 significant digits) that rounds to ``value`` in float32.

    Defined as the first of ``float(f"{value:.{n}g}")`` for n = 6, 7, 8, 9 that converts back
    to ``value``'s float32 bits, so nothing is lost: 24.280000686645508 (float32 of 24.28)
    gives 24.28. A value that is no float32 (NaN, a double float32 cannot hold) is returned
    as it is; so are ±0.0 and ±inf.
    """
    if not value:
        return value
    decimal = _DECIMALS.get(value)
    if decimal is None:
        decimal = _shortest(value)
        if decimal == decimal:  # never a NaN key: each NaN is a new object, never found
            if len(_DECIMALS) >= _DECIMALS_MAX:
                _DECIMALS.clear()
            _DECIMALS[value] = decimal
    return decimal


class _Float32Field:
    """Reads a GalileoStatus field as float32_decimal of the wire value the instance keeps.

    Reading converts, not decoding: a status frame costs nothing more to decode, and a value
    nobody reads is never converted. A data descriptor, so it comes before the instance's
    ``__dict__``, where pydantic and the decoder keep the wire value.
    """

    __slots__ = ("name",)

    def __init__(self, name: str) -> None:
        self.name = name

    def __get__(self, status: object, owner: type | None = None) -> Any:
        if status is None:
            return self
        value = status.__dict__[self.name]
        if not value:  # None, 0.0, -0.0
            return value
        decimal = _DECIMALS.get(value)
        return float32_decimal(value) if decimal is None else decimal

    def __set__(self, status: object, value: Any) -> None:
        status.__dict__[self.name] = value  # pydantic's frozen check came first


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
    """Wire layout a status frame was decoded from (docs/protocol.md §1; udp_*: §7)."""

    V1 = "v1"
    V1_CHARGE = "v1_charge"
    V2_TRUNCATED = "v2_truncated"
    V2 = "v2"
    ROS = "ros"
    #: The UDP port's 44-byte status frame, without target_distance (docs/protocol.md §7.3).
    UDP_V1 = "udp_v1"
    #: The UDP port's 48-byte status frame, with target_distance (docs/protocol.md §7.2).
    UDP_V2 = "udp_v2"

    def __str__(self) -> str:
        return self.value


class LinkState(enum.Enum):
    """Where a link is; one outage goes UP → STALE → LOST → UP, each step reported once.

    The link keeps it (transports.Link.state); read it as ``Robot.link_state``.
    """

    #: Opened the first time, or opening; no valid frame yet.
    CONNECTING = "connecting"
    #: Valid status frames arrive.
    UP = "up"
    #: Connected, but no valid frame for stale_timeout.
    STALE = "stale"
    #: The transport dropped or was given up; it stays lost, reopened or not, until a
    #: valid frame arrives (a reopened port nobody answers on is still lost).
    LOST = "lost"
    #: close() has started.
    CLOSED = "closed"


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
    """One decoded status frame; fields its layout lacks are None, never zero.

    The FLOAT32_FIELDS read, dump and show as float32_decimal of the wire value (24.28, not
    24.280000686645508), and two statuses are equal when their fields read the same.
    StatusDecoder.feed_raw gives the wire values themselves.
    """

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

    @field_serializer(*FLOAT32_FIELDS)
    def _float32_decimal(self, value: float | None) -> float | None:
        return None if value is None else float32_decimal(value)

    def __eq__(self, other: object) -> bool:
        """Equal when of one type and every field reads the same (24.28 and its float32 too)."""
        if not isinstance(other, BaseModel):
            return NotImplemented
        if type(other) is not type(self):
            return False
        return self.__dict__ == other.__dict__ or self._read() == other._read()

    def __hash__(self) -> int:
        return hash(self._read())

    def _read(self) -> tuple[Any, ...]:
        """Every field's value as it reads (the FLOAT32_FIELDS as decimals)."""
        return tuple(getattr(self, name) for name in _FIELD_NAMES)

    def __repr_args__(self) -> Iterator[tuple[str | None, Any]]:
        for name, value in super().__repr_args__():
            yield name, getattr(self, name) if name in _FLOAT32 else value

    def __iter__(self) -> Generator[tuple[str, Any], None, None]:
        for name, value in super().__iter__():
            yield name, getattr(self, name) if name in _FLOAT32 else value

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
    def is_placeholder(self) -> bool:
        """The serial node's start-up defaults, not the robot's status (docs/protocol.md §1)."""
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


#: Names of the wire fields, in the order of the current (v2) struct.
STATUS_FIELDS: tuple[str, ...] = tuple(n for n in GalileoStatus.model_fields if n != "layout")
_FLOAT32 = frozenset(FLOAT32_FIELDS)
_FIELD_NAMES = tuple(GalileoStatus.model_fields)
for _name in FLOAT32_FIELDS:  # after pydantic built the class: it must not see them as defaults
    setattr(GalileoStatus, _name, _Float32Field(_name))
