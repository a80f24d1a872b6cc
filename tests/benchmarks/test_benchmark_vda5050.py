"""The VDA 5050 benchmark's code runs (a tiny fleet, a short window) so that it cannot rot."""

from __future__ import annotations

import math
import os

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
    assert driven["lags"]
    assert not bare["in_vehicle"]


UNITS = ["% core", "cores", "cores", "cores", "KiB", "ms", "ms", "ms", "ms", "ms", "ms"]


def test_vda5050_benchmark_rows() -> None:
    require_mosquitto()
    rows = vda5050.run(quick=True, vehicles=2, seconds=0.5)
    assert [row.unit for row in rows] == UNITS
    values = {row.metric: row.value for row in rows}
    assert all(math.isfinite(value) for name, value in values.items() if "server" not in name)
    assert math.isnan(values["robots' server CPU"])  # no server: the robots are in-process
    assert rows[4].value > 0  # RSS per vehicle
    assert rows[6].target == "≤ 50 ms"
    assert rows[0].extra["robots"] == "in-process sim://"


def test_vda5050_benchmark_robots_in_their_own_process() -> None:
    require_mosquitto()
    rows = vda5050.run(quick=True, vehicles=3, seconds=1.0, robots_process=True)
    assert [row.unit for row in rows] == UNITS
    assert all(math.isfinite(row.value) for row in rows)
    assert rows[0].extra["robots"] == "fleet_server process, socket://"
    assert rows[0].baseline_name == "socket:// robot, no vehicle"
    # The server was measured (NaN when there is none); /proc counts CPU in 10 ms ticks, so
    # three idle robots over one second may show none.
    assert rows[3].value >= 0
    assert rows[3].baseline is not None
    assert rows[3].baseline >= 0
    assert rows[0].extra["samples"] > 0  # flips went over the socket and reached the master
    assert rows[1].target == "≤ 0.0015 cores"  # 0.5 cores per 1000, pro rata


def test_process_cpu_reads_proc_stat() -> None:
    assert vda5050.process_cpu(os.getpid()) > 0
    assert math.isnan(vda5050.process_cpu(2**22 + 1))  # above pid_max: no such process
