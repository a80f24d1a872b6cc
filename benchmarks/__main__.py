"""``python -m benchmarks [--quick] [NAME …] [--fleet N,…]``: NAME among BENCHMARKS below.

``python -m benchmarks fleet_merged --traffic burst|spread|both``: how the robots' frames arrive.

``python -m benchmarks vda5050 [--vehicles N] [--[no-]robots-process]``: N VDA 5050 vehicles on
one loop (Mosquitto); the robots in another process by default from 500 vehicles on.

``python -m benchmarks foxglove [--rate HZ]``: 1000 robots (another process, socket://) behind
one Foxglove server, with no viewer and with one subscribed to everything (--quick: 50).
``python -m benchmarks metrics [--robots N] [--[no-]robots-process]``: one Metrics following N
robots (default 1000): its CPU and memory, scrape times.

``python -m benchmarks breakdown [--instructions]``: the fleet's per-frame cost, stage by stage.

``python -m benchmarks compare --before DIR [--after DIR] [--rounds N] [--quick] [NAME …]``:
before and after a change, interleaved in one run (compare.py).

``python -m benchmarks lines --before DIR [--after DIR]``: source lines and modules of both trees.
"""

from __future__ import annotations

import argparse
import importlib
import json
import sys
import time
from pathlib import Path

from .common import Row, machine, render_table

BENCHMARKS = (
    "ingest", "latency", "fleet", "fleet_merged", "vda5050", "foxglove", "metrics", "virtual",
    "imports",
)  # fmt: skip
#: Run only when named: analysis, not targets.
EXTRA = ("breakdown", "mcap")
RESULTS = Path(__file__).resolve().parent / "results"


def main(argv: list[str] | None = None) -> int:
    """Run the selected benchmarks, print the table, write JSON; 1 if a target failed."""
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] in (["compare"], ["lines"]):
        from .compare import main as compare_main

        return compare_main(argv)
    parser = argparse.ArgumentParser(prog="python -m benchmarks", description=__doc__)
    parser.add_argument(
        "names",
        nargs="*",
        choices=[*BENCHMARKS, *EXTRA, []],
        metavar="NAME",
        help=f"benchmarks to run (default: all of {', '.join(BENCHMARKS)})",
    )
    parser.add_argument("--quick", action="store_true", help="fewer samples, shorter windows")
    parser.add_argument(
        "--fleet",
        default=None,
        metavar="N,N,…",
        help="fleet sizes (default 10,100,1000; --quick: 10,100)",
    )
    parser.add_argument(
        "--seconds",
        type=float,
        default=None,
        help="fleet measurement window per phase (default 6, --quick 3)",
    )
    parser.add_argument(
        "--rounds",
        type=int,
        default=None,
        help="fleet rounds of bare/driver phases (default 5 at N >= 1000, else 3; --quick 1)",
    )
    parser.add_argument(
        "--malloc",
        choices=["heap", "default"],
        default="heap",
        help="fleet: pin glibc to serve asyncio's read buffers from the heap (default), "
        "or leave it as it is (benchmarks/common.py pin_malloc)",
    )
    parser.add_argument(
        "--traffic",
        choices=["burst", "spread", "both"],
        default=None,
        help="fleet, fleet_merged: every robot's frame of a tick written together (burst: "
        "reads batched), or the frames staggered over the period (spread); default: "
        "fleet burst, fleet_merged both",
    )
    parser.add_argument(
        "--instructions",
        action="store_true",
        help="breakdown: also count instructions and L2 misses per frame (valgrind)",
    )
    parser.add_argument(
        "--vehicles", type=int, default=None, help="vda5050: vehicles (default 100; --quick 20)"
    )
    parser.add_argument(
        "--robots",
        type=int,
        default=None,
        help="metrics: robots followed (default 1000; --quick 50)",
    )
    parser.add_argument(
        "--robots-process",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="vda5050, metrics: the robots in a benchmarks.fleet_server process, connected over "
        "socket:// (spread traffic), so that the process measured runs the adapters and "
        "not the simulation (default: on from 500 vehicles, else in-process sim://)",
    )
    parser.add_argument(
        "--rate", type=float, default=None,
        help="foxglove: pose and status messages a second per robot (default 10)",
    )  # fmt: skip
    parser.add_argument("--json", type=Path, default=None, help="where to write the results")
    args = parser.parse_args(argv)  # fmt: skip
    names = args.names or list(BENCHMARKS)
    info = machine()
    print(f"{info['date']}  {info['cpu']}  nproc={info['nproc']}  Python {info['python']}  "
          f"load {info['loadavg']}", flush=True)  # fmt: skip
    rows: list[Row] = []
    started = time.monotonic()
    for name in names:
        module = importlib.import_module(f".{name}", __package__)
        print(f"running {name} …", flush=True)
        options: dict[str, object] = {"quick": args.quick}
        if name in ("fleet", "fleet_merged"):
            default = "1000" if name == "fleet_merged" else "10,100,1000"
            sizes = args.fleet or ("10,100" if args.quick else default)
            options["sizes"] = [int(n) for n in sizes.split(",")]
            options["seconds"] = args.seconds or (3.0 if args.quick else 6.0)
            options["repeats"] = args.rounds
            options["malloc"] = args.malloc
        if name == "vda5050":
            options["vehicles"] = args.vehicles
            options["robots_process"] = args.robots_process
        if name == "foxglove" and args.rate is not None:
            options["rate"] = args.rate
        if name == "metrics":
            options["robots"] = args.robots
            options["robots_process"] = args.robots_process
        if name == "breakdown":
            options["instructions"] = args.instructions
        if name in ("fleet", "fleet_merged"):
            traffic = args.traffic or ("both" if name == "fleet_merged" else "burst")
            for each in ("burst", "spread") if traffic == "both" else (traffic,):
                rows += module.run(**options, traffic=each)
            continue
        rows += module.run(**options)
    print()
    print(render_table(rows))
    path = args.json or RESULTS / time.strftime("%Y%m%d-%H%M%S.json", time.gmtime())
    path.parent.mkdir(parents=True, exist_ok=True)
    result = {
        "machine": info,
        "quick": args.quick,
        "seconds": round(time.monotonic() - started, 1),
        "rows": [row.as_dict() for row in rows],
    }
    path.write_text(json.dumps(result, indent=2, default=str) + "\n")
    print(f"\nwritten to {path}")
    return 0 if all(row.ok is not False for row in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
