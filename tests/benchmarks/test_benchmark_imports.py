"""The imports benchmark times fresh interpreters and reports what they loaded."""

from __future__ import annotations

from benchmarks import imports


def test_imports_benchmark_reports_each_module_against_asyncio() -> None:
    rows = imports.run(samples=1)
    assert [row.metric for row in rows] == [f"import {m} (median)" for m in imports.MODULES]
    assert all(row.value > 0 and row.baseline == rows[0].value for row in rows)
    assert rows[0].extra["loaded"] == ["asyncio"]


def test_a_sample_names_the_heavy_modules_it_loaded() -> None:
    seconds, loaded = imports.sample("json")
    assert seconds > 0
    assert loaded == []
