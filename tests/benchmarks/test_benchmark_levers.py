"""The build levers' probe times each way to a status, and each way builds what it claims."""

from __future__ import annotations

from benchmarks import levers


def test_levers_time_every_way() -> None:
    times = levers.measure(number=50, repeat=1)
    assert list(times) == [
        "pydantic fast build",
        "plain slotted record",
        "unchanged frame: previous status, new time_stamp",
        "call overhead",
    ]
    assert all(ns > 0 for ns in times.values())


def test_the_plain_record_holds_the_status_fields() -> None:
    build = levers._record_builder(("nav_status", "power"))
    record = build((1, 24.5))
    assert (record.layout, record.nav_status, record.power) == ("v2", 1, 24.5)  # type: ignore[attr-defined]
    assert record.nav_status.name == "OPEN"  # type: ignore[attr-defined]
