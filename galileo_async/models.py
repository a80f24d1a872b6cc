"""Status record, Pose and the wire enums shared by every layer (docs/protocol.md §1).

GalileoStatus is a plain slotted record that keeps the pydantic-style API (``model_dump``,
``model_copy``, ``model_validate``, …): a companion pydantic model, built on first use,
validates, dumps and describes it; the decoders build records without it. Pose is a
pydantic model. The enums, field names and float32 decimals live in ``_wire`` (no
pydantic), which the sans-IO core imports (docs/architecture.md, "Import cost"), and are
re-exported here.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Mapping
from functools import cache
from operator import attrgetter
from typing import TYPE_CHECKING, Any

from pydantic import BaseModel, ConfigDict, ValidationError, field_serializer

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

if TYPE_CHECKING:
    from pydantic import GetCoreSchemaHandler
    from pydantic.fields import FieldInfo
    from pydantic_core import CoreSchema
    from typing_extensions import Self

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

#: The status fields in order: ``layout``, then the wire fields.
_FIELD_NAMES: tuple[str, ...] = ("layout", *STATUS_FIELDS)
#: Field → the slot that keeps its value: the FLOAT32_FIELDS keep the wire value under
#: ``_name`` and read through a _Float32Field.
_SLOTS: dict[str, str] = {
    name: f"_{name}" if name in FLOAT32_FIELDS else name for name in _FIELD_NAMES
}
#: Each field's default: what a layout lacks is None, never zero.
_DEFAULTS: dict[str, Any] = {"layout": StatusLayout.V2, **dict.fromkeys(STATUS_FIELDS)}
#: model_fields_set of a status every field of which was given.
_ALL_FIELDS: frozenset[str] = frozenset(_FIELD_NAMES)


class _Float32Field:
    """Reads a GalileoStatus field as float32_decimal of the wire value its slot keeps.

    Reading converts, not decoding: a status frame costs nothing more to decode, and a value
    nobody reads is never converted.
    """

    __slots__ = ("wire",)
    wire: Callable[[object], Any]

    def __set_name__(self, owner: type, name: str) -> None:
        self.wire = attrgetter(f"_{name}")  # the slot that keeps the wire value

    def __get__(self, status: GalileoStatus | None, owner: type | None = None) -> Any:
        if status is None:
            return self
        value = self.wire(status)
        if not value:  # None, 0.0, -0.0
            return value
        decimal = _DECIMALS.get(value)
        return float32_decimal(value) if decimal is None else decimal


class _ModelFields:
    """``GalileoStatus.model_fields``: the companion model's fields (name → FieldInfo)."""

    __slots__ = ()

    def __get__(self, status: object, owner: type | None = None) -> dict[str, FieldInfo]:
        return _model().model_fields


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


class GalileoStatus:
    """One decoded status frame, frozen; fields its layout lacks are None, never zero.

    The FLOAT32_FIELDS read, dump and show as float32_decimal of the wire value (24.28, not
    24.280000686645508), and two statuses are equal when their fields read the same.
    StatusDecoder.feed_raw gives the wire values themselves. Construction and
    ``model_validate`` validate (pydantic.ValidationError), assignment raises one too.
    """

    __slots__ = (  # noqa: RUF023 (the fields' order)
        "layout", "nav_status", "visual_status", "map_status", "gc_status", "gba_status",
        "charge_status", "loop_status", "_power", "target_num_id", "target_status",
        "_target_distance", "angle_goal_status", "_control_speed_x", "_control_speed_theta",
        "_current_speed_x", "_current_speed_theta", "time_stamp", "_current_pose_x",
        "_current_pose_y", "_current_angle", "busy_status", "_fields_set",
    )  # fmt: skip

    if TYPE_CHECKING:  # the fields as mypy sees them: read-only (the record is frozen)

        @property
        def layout(self) -> StatusLayout: ...
        @property
        def nav_status(self) -> NavStatus | None: ...
        @property
        def visual_status(self) -> VisualStatus | None: ...
        @property
        def map_status(self) -> MapStatus | None: ...
        @property
        def gc_status(self) -> int | None: ...
        @property
        def gba_status(self) -> int | None: ...
        @property
        def charge_status(self) -> ChargeStatus | None: ...
        @property
        def loop_status(self) -> int | None: ...
        @property
        def target_num_id(self) -> int | None: ...
        @property
        def target_status(self) -> TargetStatus | None: ...
        @property
        def angle_goal_status(self) -> AngleGoalStatus | None: ...
        @property
        def time_stamp(self) -> int | None: ...
        @property
        def busy_status(self) -> int | None: ...
        @property
        def power(self) -> float | None: ...
        @property
        def target_distance(self) -> float | None: ...
        @property
        def control_speed_x(self) -> float | None: ...
        @property
        def control_speed_theta(self) -> float | None: ...
        @property
        def current_speed_x(self) -> float | None: ...
        @property
        def current_speed_theta(self) -> float | None: ...
        @property
        def current_pose_x(self) -> float | None: ...
        @property
        def current_pose_y(self) -> float | None: ...
        @property
        def current_angle(self) -> float | None: ...

        _fields_set: frozenset[str]
    else:
        power = _Float32Field()
        target_distance = _Float32Field()
        control_speed_x = _Float32Field()
        control_speed_theta = _Float32Field()
        current_speed_x = _Float32Field()
        current_speed_theta = _Float32Field()
        current_pose_x = _Float32Field()
        current_pose_y = _Float32Field()
        current_angle = _Float32Field()

    model_fields = _ModelFields()

    def __init__(self, **data: Any) -> None:
        """Validate ``data`` (field names; unknown names are ignored) like pydantic does."""
        model = _model()(**data)
        self._fill(self, model.__dict__, frozenset(model.model_fields_set))

    @staticmethod
    def _fill(status: GalileoStatus, values: Mapping[str, Any], fields_set: frozenset[str]) -> None:
        """Store ``values`` (every field) and ``fields_set`` into a new, empty ``status``."""
        for name, slot in _SLOTS.items():
            object.__setattr__(status, slot, values[name])
        object.__setattr__(status, "_fields_set", fields_set)

    # --- frozen ---------------------------------------------------------------------------

    def __setattr__(self, name: str, value: Any) -> None:
        raise _frozen(name, value)

    def __delattr__(self, name: str) -> None:
        raise _frozen(name, None)

    def __copy__(self) -> Self:
        return self

    def __deepcopy__(self, memo: dict[int, Any]) -> Self:
        return self

    def __reduce__(self) -> tuple[Any, ...]:
        return _restored, (type(self), _WIRE(self), self._fields_set)

    # --- what the fields read -------------------------------------------------------------

    def __eq__(self, other: object) -> bool:
        """Equal when of one type and every field reads the same (24.28 and its float32 too)."""
        if not isinstance(other, GalileoStatus):
            return NotImplemented
        if type(other) is not type(self):
            return False
        return _WIRE(self) == _WIRE(other) or _READ(self) == _READ(other)

    def __hash__(self) -> int:
        return hash(_READ(self))

    def __iter__(self) -> Iterator[tuple[str, Any]]:
        """(name, value) per field, as the fields read: ``dict(status)``."""
        return zip(_FIELD_NAMES, _READ(self), strict=True)

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self._fields(', ')})"

    def __str__(self) -> str:
        return self._fields(" ")

    def _fields(self, separator: str) -> str:
        return separator.join(f"{name}={value!r}" for name, value in self)

    # --- the pydantic-style API, through the companion model ------------------------------

    @property
    def model_fields_set(self) -> set[str]:
        """The fields given explicitly when built (a decoder gives its layout's fields)."""
        return set(self._fields_set)

    def model_dump(self, **options: Any) -> dict[str, Any]:
        """As pydantic's ``model_dump`` (``mode``, ``include``, ``exclude``, …)."""
        dumped: dict[str, Any] = self._model().model_dump(**options)
        return dumped

    def model_dump_json(self, **options: Any) -> str:
        """As pydantic's ``model_dump_json``; the FLOAT32_FIELDS as their decimals."""
        return self._model().model_dump_json(**options)

    def model_copy(self, *, update: Mapping[str, Any] | None = None, deep: bool = False) -> Self:
        """A status with ``update``'s fields replaced, not validated (as pydantic's).

        ``deep`` changes nothing: every value is immutable. An unknown name is a ValueError.
        """
        if not update:
            return self
        unknown = update.keys() - _SLOTS.keys()
        if unknown:
            raise ValueError(f"not GalileoStatus fields: {sorted(unknown)}")
        values = dict(zip(_FIELD_NAMES, _WIRE(self), strict=True))
        values.update(update)
        copied = object.__new__(type(self))
        self._fill(copied, values, self._fields_set | update.keys())
        return copied

    @classmethod
    def model_validate(cls, obj: Any, **options: Any) -> Self:
        """A status from a mapping or an object (pydantic's options); a status is itself."""
        if isinstance(obj, cls):
            return obj
        return cls._from_model(_model().model_validate(obj, **options))

    @classmethod
    def model_validate_json(cls, json_data: str | bytes | bytearray, **options: Any) -> Self:
        """A status from JSON, validated (pydantic's options)."""
        return cls._from_model(_model().model_validate_json(json_data, **options))

    @classmethod
    def model_json_schema(cls, **options: Any) -> dict[str, Any]:
        """The JSON schema of a status (pydantic's options)."""
        return _model().model_json_schema(**options)

    @classmethod
    def __get_pydantic_core_schema__(cls, source: Any, handler: GetCoreSchemaHandler) -> CoreSchema:
        """As a field of a pydantic model: validated, dumped and described as the companion."""
        from pydantic_core import core_schema

        model = handler.generate_schema(_model())
        return core_schema.no_info_after_validator_function(
            cls._from_model,
            core_schema.no_info_before_validator_function(_as_model, model),
            serialization=core_schema.wrap_serializer_function_ser_schema(
                lambda status, dump: dump(_as_model(status)), schema=model
            ),
        )

    @classmethod
    def _from_model(cls, model: BaseModel) -> Self:
        status = object.__new__(cls)
        cls._fill(status, model.__dict__, frozenset(model.model_fields_set))
        return status

    def _model(self) -> BaseModel:
        """The companion model of this status (wire values, fields set), unvalidated."""
        values = dict(zip(_FIELD_NAMES, _WIRE(self), strict=True))
        return _model().model_construct(set(self._fields_set), **values)

    # --- what the fields mean -------------------------------------------------------------

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


class _Filling(GalileoStatus):
    """A GalileoStatus being filled: writable; a builder then sets its ``__class__``.

    The decoders' builders store every slot as a plain attribute (which CPython specialises)
    and turn the object into a GalileoStatus: the two classes share one layout.
    """

    __slots__ = ()
    __init__ = object.__init__
    # Both: CPython specialises a store only where neither is Python code.
    __setattr__ = object.__setattr__  # type: ignore[assignment]
    __delattr__ = object.__delattr__


#: A status's power as the wire value it keeps (no float32_decimal): for code that only
#: compares it with zero, on every frame (StatusStore.update).
_wire_power: Callable[[GalileoStatus], float | None] = attrgetter("_power")
#: A status's pose as the wire values it keeps, for code that reads it on every frame
#: (galileo_async.metrics' odometer): a field's float32_decimal costs more than the read.
_wire_pose_x: Callable[[GalileoStatus], float | None] = attrgetter("_current_pose_x")
_wire_pose_y: Callable[[GalileoStatus], float | None] = attrgetter("_current_pose_y")
#: Every slot's value of a status, in _FIELD_NAMES order (the wire values).
_WIRE = attrgetter(*_SLOTS.values())
#: Every field as it reads, in _FIELD_NAMES order.
_READ = attrgetter(*_FIELD_NAMES)


def _restored(
    cls: type[GalileoStatus], values: tuple[Any, ...], fields_set: frozenset[str]
) -> GalileoStatus:
    """A status from what ``__reduce__`` gave: pickles and copies."""
    status = object.__new__(cls)
    cls._fill(status, dict(zip(_FIELD_NAMES, values, strict=True)), fields_set)
    return status


def _as_model(value: Any) -> Any:
    """A status's companion model; anything else as it is."""
    return value._model() if isinstance(value, GalileoStatus) else value


def _frozen(name: str, value: Any) -> ValidationError:
    """What assigning to a status raises, as pydantic's frozen models do."""
    return ValidationError.from_exception_data(
        "GalileoStatus", [{"type": "frozen_instance", "loc": (name,), "input": value}]
    )


@cache
def _model() -> type[BaseModel]:
    """The companion pydantic model of GalileoStatus, built on first use."""

    class GalileoStatus(BaseModel):  # its name: the title of its errors and schemas
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

    return GalileoStatus
