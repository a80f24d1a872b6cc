"""Smoke test of the fleet.statuses() benchmark with a tiny fleet (figures are not checked)."""

from __future__ import annotations

import pytest

from benchmarks import fleet_merged

HOW = ("one fleet.statuses() consumer", "a statuses() task per robot",
       "driver alone (no task per robot)")  # fmt: skip


@pytest.mark.parametrize("traffic", ["burst", "spread"])
def test_merged_benchmark_runs_and_reports_every_row(traffic: str) -> None:
    rows = fleet_merged.run(
        quick=True, sizes=[3], seconds=0.3, repeats=1, malloc="default", traffic=traffic
    )
    metrics = [row.metric for row in rows]
    assert metrics == [
        *(
            metric
            for how in HOW
            for metric in (
                f"frames kept, {how}",
                f"driver CPU, {how}",
                f"status age p99, {how}",
                f"memory per robot: RSS growth, {how}",
            )
        ),
        "fleet monitor: one screen drawn (median)",
    ]
    assert all(row.benchmark == f"fleet.statuses() N=3 {traffic}" for row in rows)
    cpu = rows[1]
    assert cpu.extra["statuses_received_per_frame"] > 0  # the one consumer got statuses
    assert cpu.extra["traffic"] == traffic
    assert all(row.extra["samples"] > 0 for row in rows if row.metric.startswith("status age"))
    assert all(row.ok is None for row in rows)  # targets are held at N=1000 only
