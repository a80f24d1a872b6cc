"""The build levers' probe times each way to a status, and each way builds what it claims."""

from __future__ import annotations

from benchmarks import levers
from galileo_async.models import GalileoStatus, StatusLayout, _model
from galileo_async.protocol import LAYOUTS
from tests.support import vectors as v


def test_levers_time_every_way() -> None:
    times = levers.measure(number=50, repeat=1)
    assert list(times) == [
        "decoder build (GalileoStatus record)",
        "pydantic model, as before the record",
        "bare slotted record",
        "unchanged frame: previous status, new time_stamp",
        "call overhead",
    ]
    assert all(ns > 0 for ns in times.values())


def test_the_plain_record_holds_the_status_fields() -> None:
    build = levers._record_builder(("nav_status", "power"))
    record = build((1, 24.5))
    assert (record.layout, record.nav_status, record.power) == ("v2", 1, 24.5)  # type: ignore[attr-defined]
    assert record.nav_status.name == "OPEN"  # type: ignore[attr-defined]


def test_the_old_way_builds_the_pydantic_model_of_the_status() -> None:
    names = LAYOUTS[StatusLayout.V2].fields
    expected = v.V2_ACTIVE_STATUS
    raw = tuple(getattr(expected, name) for name in names)
    built = levers._model_builder(names)(raw)
    assert type(built) is _model()
    assert built == _model()(**expected.model_dump())


def test_the_slot_copy_is_the_status_once_it_is_one_again() -> None:
    copied = levers._record_copier(GalileoStatus.__slots__)(v.V2_ACTIVE_STATUS)
    copied.__class__ = GalileoStatus
    assert copied == v.V2_ACTIVE_STATUS
    assert copied is not v.V2_ACTIVE_STATUS
