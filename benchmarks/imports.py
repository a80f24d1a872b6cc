"""Imports: how long ``import X`` takes in a fresh interpreter, against ``import asyncio``.

Each sample is a new process (``sys.executable -c``) that times one import statement with
``time.perf_counter`` and reports which of pydantic and asyncio it loaded; the modules take
turns (asyncio, galileo_async, galileo_async.protocol, asyncio, …) so that all see the same
machine. The figure is the median of the samples; the ratio is to ``import asyncio``'s median
in the same run. An untimed round comes first, and the interpreters may write bytecode
(``PYTHONDONTWRITEBYTECODE`` and ``PYTHONPYCACHEPREFIX`` are dropped from their
environment), so that every module is imported from its cached bytecode, as an installed
package is.
"""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys

from .common import Row

__all__ = ["MODULES", "run", "sample"]

#: The imports timed, the baseline first.
MODULES = ("asyncio", "galileo_async", "galileo_async.protocol")
#: galileo_async's target: at most this many times ``import asyncio``.
TARGET_RATIO = 2.0
#: Environment variables that would make every sample compile its modules from source.
_NO_BYTECODE = ("PYTHONDONTWRITEBYTECODE", "PYTHONPYCACHEPREFIX")
_PROBE = """
import sys, time
began = time.perf_counter()
import {module}
took = time.perf_counter() - began
print(__import__("json").dumps({{"seconds": took,
      "loaded": sorted(m for m in ("pydantic", "asyncio") if m in sys.modules)}}))
"""


def sample(module: str) -> tuple[float, list[str]]:
    """Seconds ``import module`` took in a fresh interpreter; which of pydantic, asyncio loaded."""
    env = {k: v for k, v in os.environ.items() if k not in _NO_BYTECODE}
    out = subprocess.run(
        [sys.executable, "-c", _PROBE.format(module=module)],
        check=True, capture_output=True, text=True, env=env,
    ).stdout  # fmt: skip
    reply = json.loads(out.strip().splitlines()[-1])
    return float(reply["seconds"]), list(reply["loaded"])


def run(*, quick: bool = False, samples: int | None = None) -> list[Row]:
    """Time each of MODULES ``samples`` times (default 21; --quick 5), interleaved."""
    count = samples or (5 if quick else 21)
    print(f"  imports, {count} fresh interpreters per module …", flush=True)
    times: dict[str, list[float]] = {module: [] for module in MODULES}
    loaded: dict[str, list[str]] = {}
    for module in MODULES:  # untimed: writes the bytecode the timed samples read
        sample(module)
    for _ in range(count):
        for module in MODULES:
            seconds, modules = sample(module)
            times[module].append(seconds)
            loaded[module] = modules
    base = statistics.median(times["asyncio"])
    rows = []
    for module in MODULES:
        median = statistics.median(times[module])
        ratio = median / base
        extra = {
            "ratio": round(ratio, 2),
            "min_ms": round(1000 * min(times[module]), 1),
            "max_ms": round(1000 * max(times[module]), 1),
            "samples": count,
            "loaded": loaded[module],
        }
        if module == "galileo_async":
            target, ok = f"≤ {TARGET_RATIO:g}× import asyncio", ratio <= TARGET_RATIO
        elif module == "galileo_async.protocol":
            target, ok = "loads neither pydantic nor asyncio", not loaded[module]
        else:
            target, ok = "", None
        rows.append(
            Row("imports", f"import {module} (median)", 1000 * median, "ms", 1000 * base,
                "import asyncio", target, ok, extra)
        )  # fmt: skip
    return rows
