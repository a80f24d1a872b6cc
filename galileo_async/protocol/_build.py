"""Statuses from already-typed decoder values, without validation (the decoders only).

A GalileoStatus is a slotted record: a builder fills a writable twin of it (``_Filling``,
the same layout), one plain attribute store per slot, then makes it a GalileoStatus by
setting its ``__class__``. Nothing here needs pydantic.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

from ..models import (
    _ALL_FIELDS,
    _DEFAULTS,
    _SLOTS,
    GalileoStatus,
    StatusLayout,
    _Filling,
)

__all__ = ["status_builder", "trusted_status"]


def trusted_status(values: Mapping[str, Any]) -> GalileoStatus:
    """Build from already-typed decoder values without validation.

    Keys must be field names; missing fields take their defaults (and are not in
    ``model_fields_set``).
    """
    if len(values) == len(_SLOTS):  # every field given (the keys are field names)
        return _from_mapping(values, _ALL_FIELDS)
    return _from_mapping({**_DEFAULTS, **values}, frozenset(values))


def status_builder(
    layout: StatusLayout, fields: Sequence[str], maps: Mapping[str, Mapping[int, Any]]
) -> Callable[[tuple[Any, ...]], GalileoStatus]:
    """A function: raw values named ``fields`` in order → status, like ``trusted_status``.

    A field in ``maps`` is looked up there (an enum map); the others are taken as they
    are, so the caller guarantees the types. Fields not in ``fields`` keep defaults.
    """
    names = tuple(fields)
    unknown = set(names) - _SLOTS.keys()
    if unknown or "layout" in names or len(set(names)) != len(names):
        raise ValueError(f"not distinct status fields: {names}")
    namespace: dict[str, Any] = {
        "Filling": _Filling, "cls": GalileoStatus, "layout": layout,
        "fields_set": _ALL_FIELDS if len(names) + 1 == len(_SLOTS)
        else frozenset((*names, "layout")),
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
    """Source of ``build(values)`` for status_builder (names of ``namespace``).

    Generated like dataclasses' __init__: one attribute store per slot, in the record's
    order, which CPython specialises. ``fast`` looks enum values up in exact dicts, whose
    lookup CPython also specialises, and falls back to ``build_any`` (the maps themselves,
    which make pseudo-members of unknown values) on a value they lack.
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
    lines.append("    status = Filling()")  # a plain call: object.__new__ parses its arguments
    for name, slot in _SLOTS.items():  # "layout" among them
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
            namespace[f"default_{name}"] = _DEFAULTS[name]
            value = f"default_{name}"
        lines.append(f"    status.{slot} = {value}")
    lines += [
        "    status._fields_set = fields_set",
        "    status.__class__ = cls",
        "    return status",
    ]
    return "\n".join(lines) + "\n"


def _mapping_source() -> str:
    """Source of ``from_mapping(values, fields_set)``: every field read from ``values``."""
    lines = ["def from_mapping(values, fields_set):", "    status = Filling()"]
    lines += [f"    status.{slot} = values[{name!r}]" for name, slot in _SLOTS.items()]
    lines += [
        "    status._fields_set = fields_set",
        "    status.__class__ = cls",
        "    return status",
    ]
    return "\n".join(lines) + "\n"


_NAMESPACE: dict[str, Any] = {"Filling": _Filling, "cls": GalileoStatus}
exec(_mapping_source(), _NAMESPACE)
_from_mapping: Callable[[Mapping[str, Any], frozenset[str]], GalileoStatus] = _NAMESPACE[
    "from_mapping"
]
