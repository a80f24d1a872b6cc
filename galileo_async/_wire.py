"""Wire enums, status field names and float32 decimals: models.py without pydantic.

Import them from ``galileo_async.models``; the sans-IO core (``galileo_async.protocol``)
imports them from here, so that it loads no pydantic (docs/architecture.md, "Import cost").
"""

from __future__ import annotations

import enum
import struct
from typing import Any

__all__ = [
    "FLOAT32_FIELDS",
    "STATUS_FIELDS",
    "AngleGoalStatus",
    "ChargeStatus",
    "LinkState",
    "MapStatus",
    "NavStatus",
    "StatusLayout",
    "TargetStatus",
    "VisualStatus",
    "float32_decimal",
]

#: Names of the wire fields, in the order of the current (v2) struct: GalileoStatus's fields
#: but ``layout`` (tests/protocol/test_models.py holds the two together).
STATUS_FIELDS: tuple[str, ...] = (
    "nav_status", "visual_status", "map_status", "gc_status", "gba_status", "charge_status",
    "loop_status", "power", "target_num_id", "target_status", "target_distance",
    "angle_goal_status", "control_speed_x", "control_speed_theta", "current_speed_x",
    "current_speed_theta", "time_stamp", "current_pose_x", "current_pose_y", "current_angle",
    "busy_status",
)  # fmt: skip

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
