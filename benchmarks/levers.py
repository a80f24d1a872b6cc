"""What building one v2 status costs, and what issue 33's levers would take off it.

``python -m benchmarks.levers``: in this process, the best of 7 repetitions of 200,000
calls each, ns per call, for the same unpacked values of a v2 frame:

* **decoder build**: the decoder's builder (``protocol/_build.py``), a GalileoStatus record;
* **pydantic model, as before the record**: what the decoder did while GalileoStatus was a
  pydantic model: the same stores into a holder whose dict became a model's, whose three
  slots were set (the companion model stands in for it);
* **bare slotted record**: the same 22 attribute stores and 6 enum lookups into a plain
  ``__slots__`` object of its own, the floor of any record;
* **unchanged frame**: the previous status reused with a new time_stamp (compare the
  values but for the counter, copy the previous status's slots, one store more);
* **call overhead**: a function that does nothing, the harness's own share.

Not part of ``python -m benchmarks``: a measurement for BENCHMARKS.md §9, not a target.
"""

from __future__ import annotations

import timeit
from collections.abc import Callable
from typing import Any

from pydantic import BaseModel

from galileo_async.models import GalileoStatus, NavStatus, _Filling, _model
from galileo_async.protocol import encode_status
from galileo_async.protocol import status as decoding
from galileo_async.protocol.layouts import ENUM_FIELDS, LAYOUTS

NUMBER = 200_000
REPEAT = 7


def _record_builder(names: tuple[str, ...]) -> Callable[[tuple[Any, ...]], object]:
    """A builder of plain slotted records, generated as the status builder is."""
    record = type("Record", (), {"__slots__": ("layout", *names)})
    namespace: dict[str, Any] = {"new": object.__new__, "Record": record}
    lines = ["def build(values):", "    r = new(Record)"]
    lines.append("    " + ", ".join(f"v{i}" for i in range(len(names))) + ", = values")
    for index, name in enumerate(names):
        if name in ENUM_FIELDS:
            namespace[f"m_{name}"] = dict(ENUM_FIELDS[name]._value2member_map_)
            lines.append(f"    r.{name} = m_{name}[v{index}]")
        else:
            lines.append(f"    r.{name} = v{index}")
    lines += ["    r.layout = 'v2'", "    return r"]
    exec("\n".join(lines) + "\n", namespace)
    build: Callable[[tuple[Any, ...]], object] = namespace["build"]
    return build


def _model_builder(names: tuple[str, ...]) -> Callable[[tuple[Any, ...]], object]:
    """The decoder's build while GalileoStatus was a pydantic model (its fast path)."""
    model = _model()
    holder = type("Compact", (), {})
    setters = {
        name: vars(BaseModel)[name].__set__
        for name in (
            "__dict__",
            "__pydantic_fields_set__",
            "__pydantic_extra__",
            "__pydantic_private__",
        )
    }
    namespace: dict[str, Any] = {
        "new": object.__new__, "cls": model, "Compact": holder, "fields_set": set(),
        **{f"set{index}": setter for index, setter in enumerate(setters.values())},
    }  # fmt: skip
    lines = ["def build(values):"]
    lines.append("    " + ", ".join(f"v{i}" for i in range(len(names))) + ", = values")
    lines.append("    f = Compact()")
    for index, name in enumerate(names):
        if name in ENUM_FIELDS:
            namespace[f"m_{name}"] = dict(ENUM_FIELDS[name]._value2member_map_)
            lines.append(f"    f.{name} = m_{name}[v{index}]")
        else:
            lines.append(f"    f.{name} = v{index}")
    lines += [
        "    f.layout = 'v2'", "    s = new(cls)", "    set0(s, f.__dict__)",
        "    set1(s, fields_set)", "    set2(s, None)", "    set3(s, None)", "    return s",
    ]  # fmt: skip
    exec("\n".join(lines) + "\n", namespace)
    build: Callable[[tuple[Any, ...]], object] = namespace["build"]
    return build


def _record_copier(slots: tuple[str, ...]) -> Callable[[GalileoStatus], Any]:
    """A function: status → a writable copy of it (a ``_Filling``), slot by slot."""
    namespace: dict[str, Any] = {"Filling": _Filling}
    lines = ["def copy(previous):", "    s = Filling()"]
    lines += [f"    s.{slot} = previous.{slot}" for slot in slots]
    lines.append("    return s")
    exec("\n".join(lines) + "\n", namespace)
    copier: Callable[[GalileoStatus], Any] = namespace["copy"]
    return copier


def measure(number: int = NUMBER, repeat: int = REPEAT) -> dict[str, float]:
    """ns per call of each way to a status (best of ``repeat`` runs of ``number`` calls)."""
    names = LAYOUTS["v2"].fields
    frame = encode_status(
        GalileoStatus(power=24.28, time_stamp=3, nav_status=NavStatus.OPEN, current_pose_x=1.5)
    )
    values = decoding.StatusDecoder().feed_raw(frame)[0][1]
    build = decoding._CONVERTERS["v2"].build
    build(values)  # loads the builders
    build = decoding._CONVERTERS["v2"].build
    stamp = names.index("time_stamp")
    previous = build(values)
    head, tail = values[:stamp], values[stamp + 1 :]

    slots = GalileoStatus.__slots__
    copy_slots = _record_copier(slots)

    def unchanged(values: tuple[Any, ...]) -> GalileoStatus | None:
        if values[:stamp] != head or values[stamp + 1 :] != tail:
            return None
        status = copy_slots(previous)
        status.time_stamp = values[stamp]
        status.__class__ = GalileoStatus
        reused: GalileoStatus = status
        return reused

    def nothing(values: tuple[Any, ...]) -> None:
        return None

    ways: dict[str, Callable[[tuple[Any, ...]], object]] = {
        "decoder build (GalileoStatus record)": build,
        "pydantic model, as before the record": _model_builder(names),
        "bare slotted record": _record_builder(names),
        "unchanged frame: previous status, new time_stamp": unchanged,
        "call overhead": nothing,
    }
    return {
        name: 1e9 * min(timeit.repeat(lambda f=f: f(values), number=number, repeat=repeat)) / number  # type: ignore[misc]
        for name, f in ways.items()
    }


def main() -> None:
    """Print ns per call of each way."""
    for name, ns in measure().items():
        print(f"{name:52} {ns:7.0f} ns")


if __name__ == "__main__":
    main()
