"""The metrics benchmark's code runs (a few robots, short windows) so that it cannot rot."""

from __future__ import annotations

import math

from benchmarks import metrics

UNITS = ["% core", "cores", "bytes", "ms", "ms", "ms", "ms", "ms", "ms", "ms", "ms", "ms", "KiB"]


def test_metrics_benchmark_rows() -> None:
    rows = metrics.run(quick=True, robots=3, seconds=0.3)
    assert [row.unit for row in rows] == UNITS
    assert all(math.isfinite(row.value) for row in rows)
    assert rows[7].value > 0  # the read and encoding of a scrape cost CPU
    assert rows[9].value > 0  # the longest step
    assert rows[10].unit == "ms"  # CPU per scrape over HTTP: a difference, may come out < 0
    assert rows[0].baseline is not None
    assert rows[0].baseline > 0
    assert rows[0].extra["where"] == "in-process sim://"
    assert rows[3].value > 0  # a scrape takes time
    assert rows[11].baseline is not None  # the loop's lag measured without scrapes too
    assert rows[12].value > 0  # a scrape carries the robots' series
    assert rows[12].extra["openmetrics_kib"] > 0


def test_metrics_benchmark_robots_in_their_own_process() -> None:
    rows = metrics.run(quick=True, robots=3, seconds=0.3, robots_process=True)
    assert rows[0].extra["where"] == "fleet_server process, socket://"
    assert all(math.isfinite(row.value) for row in rows)
