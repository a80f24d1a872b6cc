"""Shared pieces of the benchmarks: result rows, machine facts, percentiles, the table."""

from __future__ import annotations

import ctypes
import math
import os
import platform
import resource
import sys
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from datetime import datetime, timezone
from typing import Any

__all__ = [
    "Row",
    "machine",
    "percentile",
    "pin_malloc",
    "raise_fd_limit",
    "render_table",
    "rss_bytes",
]


@dataclass
class Row:
    """One measured figure, its baseline from the same run, and the target it is held to."""

    benchmark: str
    metric: str
    value: float
    unit: str
    baseline: float | None = None
    baseline_name: str = ""
    target: str = ""
    ok: bool | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready form."""
        return asdict(self)


def percentile(values: Sequence[float], q: float) -> float:
    """The q-th percentile (0-100), nearest-rank; NaN for no values."""
    if not values:
        return math.nan
    ordered = sorted(values)
    rank = max(0, min(len(ordered) - 1, math.ceil(q / 100 * len(ordered)) - 1))
    return ordered[rank]


def rss_bytes() -> int:
    """Resident set size of this process right now (Linux /proc), else the peak."""
    try:
        with open("/proc/self/statm") as statm:
            return int(statm.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
    except OSError:
        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


#: glibc's mallopt parameters.
_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3


def pin_malloc() -> bool:
    """Pin glibc to serve asyncio's 256 KiB read buffers from the heap; False if impossible.

    A plain ``asyncio.Protocol`` gets a fresh bytes object per read, allocated at 256 KiB
    and shrunk to the bytes read. In an unpinned process that read cost about 9 µs per
    frame at some times and 15-16 µs at others, flipping unseen (BENCHMARKS.md §2); with
    glibc's mmap threshold pinned above 256 KiB (the trim threshold at twice
    that, as glibc's own adjustment sets it) the cheap state holds.
    """
    try:
        mallopt = ctypes.CDLL("libc.so.6").mallopt
    except (OSError, AttributeError):
        return False
    threshold = 1 << 20
    return bool(mallopt(_M_MMAP_THRESHOLD, threshold) and mallopt(_M_TRIM_THRESHOLD, 2 * threshold))


def raise_fd_limit() -> int:
    """Raise the soft RLIMIT_NOFILE to the hard limit; return the new soft limit."""
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    if hard == resource.RLIM_INFINITY:
        hard = 1 << 20
    if soft < hard:
        resource.setrlimit(resource.RLIMIT_NOFILE, (hard, hard))
    return resource.getrlimit(resource.RLIMIT_NOFILE)[0]


def machine() -> dict[str, Any]:
    """What the figures were measured on."""
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as info:
            for line in info:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    try:
        load = os.getloadavg()
    except OSError:
        load = (math.nan, math.nan, math.nan)
    return {
        "date": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "cpu": cpu,
        "nproc": os.cpu_count(),
        "python": sys.version.split()[0],
        "implementation": platform.python_implementation(),
        "platform": platform.platform(),
        "loadavg": [round(x, 2) for x in load],
    }


def _fmt(value: float | None) -> str:
    if value is None:
        return "-"
    if math.isnan(value):
        return "nan"
    magnitude = abs(value)
    if magnitude >= 1000:
        return f"{value:,.0f}"
    if magnitude >= 10:
        return f"{value:.1f}"
    return f"{value:.3g}" if magnitude < 0.1 else f"{value:.2f}"


def render_table(rows: Sequence[Row]) -> str:
    """A plain-text table: benchmark, metric, value, baseline, target, verdict."""
    header = ("benchmark", "metric", "value", "unit", "baseline", "target", "ok")
    lines = [header]
    for row in rows:
        base = _fmt(row.baseline)
        if row.baseline is not None and row.baseline_name:
            base = f"{base} ({row.baseline_name})"
        verdict = "" if row.ok is None else ("yes" if row.ok else "NO")
        lines.append(
            (row.benchmark, row.metric, _fmt(row.value), row.unit, base, row.target, verdict)
        )
    widths = [max(len(line[i]) for line in lines) for i in range(len(header))]
    out = []
    for index, line in enumerate(lines):
        out.append(
            "  ".join(cell.ljust(width) for cell, width in zip(line, widths, strict=True)).rstrip()
        )
        if index == 0:
            out.append("  ".join("-" * width for width in widths))
    return "\n".join(out)
