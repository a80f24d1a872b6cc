"""benchmarks/virtual.py measures what it says: a 60 s goal on the virtual clock."""

from __future__ import annotations

import pytest

from benchmarks.virtual import run


def test_the_goal_is_sixty_simulated_seconds_and_has_a_baseline() -> None:
    (row,) = run(quick=True)
    assert row.extra["simulated_s"] == pytest.approx(60.0, abs=1.0)
    assert row.extra["rounds"] == 3
    assert row.value > 0
    assert row.baseline is not None
    assert row.baseline > 0
    assert row.ok is (row.value < 1000)
