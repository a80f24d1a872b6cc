"""Smoke test of the fleet.statuses() benchmark with a tiny fleet (figures are not checked)."""

from __future__ import annotations

from benchmarks import fleet_merged


def test_merged_benchmark_runs_and_reports_every_row() -> None:
    rows = fleet_merged.run(quick=True, sizes=[3], seconds=0.3, repeats=1, malloc="default")
    metrics = [row.metric for row in rows]
    assert metrics == [
        "frames kept",
        "driver CPU, one fleet.statuses() consumer",
        "a statuses() task per robot CPU (for reference)",
        "status age p99",
        "memory per robot: RSS growth",
        "fleet monitor: one screen drawn (median)",
    ]
    cpu = rows[1]
    assert cpu.extra["statuses_received_per_frame"] > 0  # the one consumer got statuses
    assert rows[3].extra["samples"] > 0
    assert all(row.ok is None for row in rows)  # targets are held at N=1000 only
