"""Statuses from already-typed decoder values, without validation, fenced by pydantic version.

``GalileoStatus.model_construct`` handles aliases, defaults and validators field by field;
the decoder's values need none of that. The fast path sets what ``model_construct`` sets
(the instance ``__dict__`` and BaseModel's three slots) directly, which is about 8x faster
(the decoder builds 30 statuses a second per robot). How pydantic stores an instance is not
its public API, so the fast path is taken only for the pydantic versions it was checked
against (``PYDANTIC_CHECKED``, decided once at import); with any other version both
functions here build with ``model_construct``, to equal statuses.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import pydantic.version
from pydantic import BaseModel

from ..models import GalileoStatus, StatusLayout

__all__ = [
    "FAST_PATH",
    "PYDANTIC_CHECKED",
    "fast_path_supported",
    "status_builder",
    "trusted_status",
]

#: Pydantic versions ``[low, high)`` (major, minor) whose BaseModel layout the fast path was
#: checked against: the decoder's and the models' tests passed with 2.7.4, 2.11.10 and
#: 2.14.4 (tests/protocol/test_build.py pins the installed version inside). Widen it only after
#: they pass with the new version.
PYDANTIC_CHECKED: tuple[tuple[int, int], tuple[int, int]] = ((2, 7), (2, 15))


def fast_path_supported(version: str) -> bool:
    """True when pydantic ``version`` (``"2.14.4"``) lies within ``PYDANTIC_CHECKED``."""
    match = re.match(r"(\d+)\.(\d+)", version)
    if match is None:
        return False
    low, high = PYDANTIC_CHECKED
    return low <= (int(match[1]), int(match[2])) < high


#: Whether this process builds statuses the fast way (the installed pydantic's version).
FAST_PATH = fast_path_supported(pydantic.version.VERSION)

_FIELD_DEFAULTS: dict[str, Any] = {
    name: field.default for name, field in GalileoStatus.model_fields.items()
}
_FIELD_COUNT = len(_FIELD_DEFAULTS)
_construct = GalileoStatus.model_construct


def trusted_status(values: dict[str, Any]) -> GalileoStatus:
    """Build from already-typed decoder values without validation; adopts ``values``.

    Keys must be field names; missing fields take their defaults. When every field is
    given the dict becomes the instance's storage, so the caller must not reuse it.
    """
    if not FAST_PATH:
        return _construct(**values)
    status = _new_status(GalileoStatus)
    fields_set: set[str]
    if len(values) == _FIELD_COUNT:  # every field given (the keys are field names)
        fields_set = _ALL_FIELDS  # shared and read-only: no set built per frame
    else:
        fields_set = set(values)
        values = {**_FIELD_DEFAULTS, **values}
    _set_dict(status, values)
    _set_fields_set(status, fields_set)
    _set_extra(status, None)
    _set_private(status, None)
    return status


def status_builder(
    layout: StatusLayout,
    fields: Sequence[str],
    maps: Mapping[str, Mapping[int, Any]],
    *,
    fast: bool = True,
) -> Callable[[tuple[Any, ...]], GalileoStatus]:
    """A function: raw values named ``fields`` in order → status, like ``trusted_status``.

    A field in ``maps`` is looked up there (an enum map); the others are taken as they
    are, so the caller guarantees the types. Fields not in ``fields`` keep defaults.
    ``fast=False`` builds with ``model_construct``, as every builder does outside
    ``PYDANTIC_CHECKED``.
    """
    names = tuple(fields)
    unknown = set(names) - _FIELD_DEFAULTS.keys()
    if unknown or "layout" in names or len(set(names)) != len(names):
        raise ValueError(f"not distinct status fields: {names}")
    if not (fast and FAST_PATH):
        return _constructing_builder(layout, names, maps)
    namespace: dict[str, Any] = {
        "new": _new_status, "cls": GalileoStatus, "set_dict": _set_dict,
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


def _constructing_builder(
    layout: StatusLayout, names: tuple[str, ...], maps: Mapping[str, Mapping[int, Any]]
) -> Callable[[tuple[Any, ...]], GalileoStatus]:
    """``status_builder`` on pydantic's public API only: ``model_construct``."""
    lookups = tuple(maps.get(name) for name in names)

    def build(values: tuple[Any, ...]) -> GalileoStatus:
        given: dict[str, Any] = {"layout": layout}
        for name, lookup, value in zip(names, lookups, values, strict=True):
            given[name] = value if lookup is None else lookup[value]
        return _construct(**given)

    return build


def _builder_source(
    names: tuple[str, ...],
    maps: Mapping[str, Mapping[int, Any]],
    namespace: dict[str, Any],
    *,
    fast: bool,
) -> str:
    """Source of ``build(values)`` for status_builder (names of ``namespace``).

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


def _slot_setter(name: str) -> Callable[[object, Any], None]:
    """The setter of BaseModel's ``name`` slot (or its ``__dict__``): a little faster."""
    setter: Callable[[object, Any], None] = vars(BaseModel)[name].__set__
    return setter


_new_status = object.__new__
_ALL_FIELDS = _SharedFieldsSet(_FIELD_DEFAULTS)
# Looked up only within PYDANTIC_CHECKED: another version may not have these at all.
if FAST_PATH:
    _set_dict = _slot_setter("__dict__")
    _set_fields_set = _slot_setter("__pydantic_fields_set__")
    _set_extra = _slot_setter("__pydantic_extra__")
    _set_private = _slot_setter("__pydantic_private__")
