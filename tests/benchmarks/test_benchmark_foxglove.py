"""The Foxglove benchmark's code runs (a few robots, a short window) so that it cannot rot."""

from __future__ import annotations

import math

import pytest

pytest.importorskip("foxglove")

from benchmarks import foxglove


def test_foxglove_benchmark_rows() -> None:
    rows = foxglove.run(quick=True, robots=3, seconds=1.0)
    assert [row.unit for row in rows] == ["% core", "% core", "cores", "cores", "KiB", "msg/s"]
    assert all(math.isfinite(row.value) for row in rows)
    assert rows[0].baseline_name == "no server"
    assert rows[0].baseline is not None
    assert rows[0].baseline > 0
    # RSS per robot: 3 robots' channels may fit in pages the process had (0 is a measure).
    assert rows[4].value >= 0
    # The client subscribed to every channel of 3 robots and got their messages.
    assert rows[5].value > 0
    assert rows[0].extra["robots"] == 3
