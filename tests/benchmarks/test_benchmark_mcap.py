"""benchmarks/mcap.py measures what it says: the recorder on and off, on the same robots."""

from __future__ import annotations

from benchmarks.mcap import run


def test_the_recorder_is_measured_next_to_its_baseline() -> None:
    rows = run(quick=True, robots=3, seconds=0.5)
    metrics = {row.metric: row for row in rows}
    cpu = metrics["CPU per frame, recorder on (the whole process)"]
    assert cpu.value > 0
    assert cpu.baseline is not None
    assert cpu.baseline > 0
    assert cpu.baseline_name == "recorder off"
    assert all(frames > 0 for frames in cpu.extra["frames"])
    disk = metrics["bytes on disk per status recorded (raw, status, events)"]
    assert disk.extra["statuses"] > 0
    assert disk.value > 0
    lag = metrics["loop lag p99 of a 10 ms sleep, recorder on"]
    assert lag.baseline is not None
    assert metrics["messages dropped (disk behind)"].value == 0
