"""Status model and wire enums shared by every layer (docs/protocol.md §1).

GalileoStatus and Pose are pydantic models; the enums, field names and float32 decimals
live in ``_wire`` (no pydantic), which the sans-IO core imports (docs/architecture.md,
"Import cost"), and are re-exported here.
"""

from __future__ import annotations

import math
from collections.abc import Generator, Iterator
from typing import Any

from pydantic import BaseModel, ConfigDict, field_serializer

from ._wire import (
    _DECIMALS,
    _PLACEHOLDER,
    FLOAT32_FIELDS,
    STATUS_FIELDS,
    AngleGoalStatus,
    ChargeStatus,
    LinkState,
    MapStatus,
    NavStatus,
    StatusLayout,
    TargetStatus,
    VisualStatus,
    float32_decimal,
)

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


_FLOAT32 = frozenset(FLOAT32_FIELDS)
_FIELD_NAMES = tuple(GalileoStatus.model_fields)
for _name in FLOAT32_FIELDS:  # after pydantic built the class: it must not see them as defaults
    setattr(GalileoStatus, _name, _Float32Field(_name))
