"""The VDA 5050 benchmark's code runs (a tiny fleet, a short window) so that it cannot rot."""

from __future__ import annotations

import math

import anyio

from benchmarks import vda5050
from tests.support.vda5050_support import require_mosquitto


def test_vda5050_benchmark_phases_measure_cpu_and_latency() -> None:
    require_mosquitto()
    with vda5050.mosquitto() as port:
        bare = anyio.run(vda5050.measure, 2, 1.0, port, False)
        driven = anyio.run(vda5050.measure, 2, 1.0, port, True)
    for phase in (bare, driven):
        assert phase["cpu_per_robot"] > 0
        assert phase["latencies"]
        assert all(0 < latency < 10 for latency in phase["latencies"])
    assert driven["in_vehicle"]
    assert not bare["in_vehicle"]


def test_vda5050_benchmark_rows() -> None:
    require_mosquitto()
    rows = vda5050.run(quick=True, vehicles=2, seconds=0.5)
    units = ["% core", "cores", "KiB", "ms", "ms", "ms", "ms", "ms"]
    assert [row.unit for row in rows] == units
    assert all(math.isfinite(row.value) for row in rows)
    assert rows[2].value > 0  # RSS per vehicle
    assert rows[4].target == "≤ 50 ms"
