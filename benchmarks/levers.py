"""What building one v2 status costs, and what issue 33's levers would take off it.

``python -m benchmarks.levers``: in this process, the best of 7 repetitions of 200,000
calls each, ns per call, for the same unpacked values of a v2 frame:

* **pydantic fast build**: the decoder's builder (``protocol/_build.py``'s fast path);
* **plain slotted record**: the same 22 attribute stores and 6 enum lookups into a
  ``__slots__`` object, what a decoder producing a plain record would do per frame;
* **unchanged frame**: the previous status reused with a new time_stamp (compare the
  values but for the counter, copy the previous status's dict, set pydantic's slots);
* **call overhead**: a function that does nothing, the harness's own share.

Not part of ``python -m benchmarks``: a measurement for BENCHMARKS.md §9, not a target.
"""

from __future__ import annotations

import timeit
from collections.abc import Callable
from typing import Any

from galileo_async.models import GalileoStatus, NavStatus
from galileo_async.protocol import _build, encode_status
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

    def unchanged(values: tuple[Any, ...]) -> GalileoStatus | None:
        if values[:stamp] != head or values[stamp + 1 :] != tail:
            return None
        fields = previous.__dict__.copy()
        fields["time_stamp"] = values[stamp]
        status: GalileoStatus = _build._new_status(GalileoStatus)
        _build._set_dict(status, fields)
        _build._set_fields_set(status, _build._ALL_FIELDS)
        _build._set_extra(status, None)
        _build._set_private(status, None)
        return status

    def nothing(values: tuple[Any, ...]) -> None:
        return None

    ways: dict[str, Callable[[tuple[Any, ...]], object]] = {
        "pydantic fast build": build,
        "plain slotted record": _record_builder(names),
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
