"""Before and after, interleaved in one run: ``python -m benchmarks compare`` and ``lines``.

``compare --before DIR [--after DIR] [--rounds N] [--quick] [NAME …]`` runs each chosen
probe (benchmarks/probe.py: ingest, fleet, latency; instructions only when named, once a
tree, under cachegrind) alternately on the two trees, B, A,
B, A, …, each run in a fresh process whose ``galileo_async`` is that tree's and whose
benchmark code is this checkout's, and prints per figure both medians, each side's
run-to-run spread (min–max over the rounds), the ratio after / before and a verdict.

``lines --before DIR [--after DIR]``: source lines and modules of ``galileo_async/``, and
files and lines of ``tests/``, in both trees.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import pickle
import re
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .common import machine

__all__ = [
    "Comparison",
    "Tree",
    "compare",
    "count_lines",
    "main",
    "render_comparison",
    "run_probe",
    "verdict",
]

THIS_CHECKOUT = Path(__file__).resolve().parents[1]
RESULTS = Path(__file__).resolve().parent / "results"
PROBE_NAMES = ("ingest", "fleet", "latency")
#: Run only when named: ingest's instructions per frame under cachegrind (deterministic).
EXTRA_NAMES = ("instructions",)
#: Frames per cachegrind run (the count, then three times it) of each part of ingest.
INSTRUCTION_FRAMES = {"decode": 1000, "path": 300}
#: Instruction counts repeat to about 0.1 %: a difference beyond this is a verdict.
INSTRUCTION_TOLERANCE = 0.01
#: Probe options: a full run, and --quick.
FULL: dict[str, Any] = {"frames": 10_000, "repeats": 5, "path_frames": 3000,
                        "samples": 2000, "ros_samples": 300, "fleet": 1000,
                        "seconds": 6.0}  # fmt: skip
QUICK: dict[str, Any] = {"frames": 3000, "repeats": 3, "path_frames": 1000,
                         "samples": 400, "ros_samples": 100, "fleet": 1000,
                         "seconds": 3.0}  # fmt: skip
#: Longest one probe process may run.
PROBE_TIMEOUT = 900.0


@dataclass
class Tree:
    """A checkout of the project whose package a probe imports."""

    label: str
    path: Path
    commit: str = ""
    staging: Path | None = None

    def describe(self) -> str:
        """``label: path @ commit``."""
        return f"{self.label}: {self.path} @ {self.commit or '?'}"


def git_commit(path: Path) -> str:
    """The tree's short commit, with "+dirty" if its tracked files differ; "" if not git."""
    try:
        head = subprocess.run(["git", "-C", str(path), "rev-parse", "--short", "HEAD"],
                              capture_output=True, text=True, check=True, timeout=30)  # fmt: skip
        dirty = subprocess.run(["git", "-C", str(path), "status", "--porcelain", "-uno"],
                               capture_output=True, text=True, check=True, timeout=30)  # fmt: skip
    except (OSError, subprocess.SubprocessError):
        return ""
    return head.stdout.strip() + ("+dirty" if dirty.stdout.strip() else "")


def stage(tree_path: Path, into: Path) -> Path:
    """A folder for PYTHONPATH: the tree's ``galileo_async`` beside this ``benchmarks``."""
    into.mkdir(parents=True, exist_ok=True)
    package = tree_path / "galileo_async"
    if not (package / "__init__.py").is_file():
        raise SystemExit(f"{tree_path} has no galileo_async package")
    (into / "galileo_async").symlink_to(package.resolve(), target_is_directory=True)
    (into / "benchmarks").symlink_to(Path(__file__).resolve().parent, target_is_directory=True)
    return into


def _env(staging: Path, server_staging: Path, cache: Path) -> dict[str, str]:
    env = {key: value for key, value in os.environ.items() if key != "PYTHONPATH"}
    env.update(
        PYTHONPATH=str(staging),
        # Bytecode goes to a folder of the run's own: the trees stay as they are.
        PYTHONPYCACHEPREFIX=str(cache),
        GALILEO_BENCH_SERVER_PATH=str(server_staging),
    )
    return env


def run_probe(
    tree: Tree,
    name: str,
    options: dict[str, Any],
    env: dict[str, str],
    cwd: Path,
    prefix: Sequence[str] = (),
) -> dict[str, Any]:
    """Run probe ``name`` in a fresh process on ``tree``; check it imported that tree's package.

    ``cwd`` must hold neither package: ``python -m`` puts it first on ``sys.path``.
    ``prefix`` runs the process under another program (valgrind).
    """
    done = subprocess.run(
        [*prefix, sys.executable, "-m", "benchmarks.probe", name, json.dumps(options)],
        cwd=cwd, env=env, capture_output=True, text=True, timeout=PROBE_TIMEOUT,
    )  # fmt: skip
    if done.returncode != 0:
        raise RuntimeError(
            f"probe {name} on {tree.describe()} failed ({done.returncode}):\n{done.stderr[-4000:]}"
        )
    result: dict[str, Any] = json.loads(done.stdout.strip().splitlines()[-1])
    package = Path(result["package"]).resolve()
    if not package.is_relative_to((tree.path / "galileo_async").resolve()):
        raise RuntimeError(f"probe {name} on {tree.describe()} imported {package}")
    return result


def instructions(
    tree: Tree, options: dict[str, Any], env: dict[str, str], cwd: Path
) -> dict[str, list[Any]]:
    """Instructions per frame of each part of ingest on ``tree``: two cachegrind runs each."""
    figures: dict[str, list[Any]] = {}
    names = {"decode": "ingest instructions: decode → GalileoStatus, per frame",
             "path": "ingest instructions: socket:// frame → 3 statuses() + 1 wait_until, "
                     "per frame"}  # fmt: skip
    for part, count in INSTRUCTION_FRAMES.items():
        totals = []
        for frames in (count, 3 * count):
            out = cwd / f"cachegrind.{tree.label}.{part}.{frames}"
            prefix = ["valgrind", "--tool=cachegrind", "--cache-sim=no",
                      f"--cachegrind-out-file={out}"]  # fmt: skip
            run_probe(tree, "work", {**options, "part": part, "count": frames}, env, cwd, prefix)
            summary = re.search(r"^summary: (\d+)", out.read_text(), re.M)
            if summary is None:
                raise RuntimeError(f"cachegrind wrote no summary to {out}")
            totals.append(int(summary.group(1)))
        figures[names[part]] = [(totals[1] - totals[0]) / (2 * count), "instructions"]
    return figures


def verdict(before: Sequence[float], after: Sequence[float]) -> str:
    """Lower is better; "slower", "faster", "within spread", or "n/a" under 2 rounds a side.

    "not run" when a value is NaN (a probe that could not measure it). "slower" only when
    the after median lies above the before side's max and exceeds the before median by
    more than the larger side's spread (max - min); "faster" the mirror.
    """
    if any(math.isnan(value) for value in (*before, *after)):
        return "not run"
    if len(before) < 2 or len(after) < 2:
        return "n/a"
    spread = max(max(before) - min(before), max(after) - min(after))
    median_before, median_after = statistics.median(before), statistics.median(after)
    difference = median_after - median_before
    if median_after > max(before) and difference > spread:
        return "slower"
    if median_after < min(before) and -difference > spread:
        return "faster"
    return "within spread"


def instruction_verdict(before: Sequence[float], after: Sequence[float]) -> str:
    """Counts repeat: "slower" / "faster" beyond INSTRUCTION_TOLERANCE, else "within spread"."""
    if not before or not after:
        return "n/a"
    ratio = statistics.median(after) / statistics.median(before)
    if ratio > 1 + INSTRUCTION_TOLERANCE:
        return "slower"
    if ratio < 1 - INSTRUCTION_TOLERANCE:
        return "faster"
    return "within spread"


@dataclass
class Comparison:
    """Every figure's values per side, in the order the probes gave them."""

    before: Tree
    after: Tree
    units: dict[str, str] = field(default_factory=dict)
    values: dict[str, dict[str, list[float]]] = field(default_factory=dict)

    def add(self, side: str, figures: dict[str, list[Any]]) -> None:
        """Record one probe run's figures for ``side`` ("before" or "after")."""
        for key, (value, unit) in figures.items():
            self.units[key] = unit
            self.values.setdefault(key, {"before": [], "after": []})[side].append(float(value))

    def rows(self) -> list[dict[str, Any]]:
        """Per figure: medians, spreads, ratio and verdict (JSON-ready)."""
        rows = []
        for key, sides in self.values.items():
            before, after = sides["before"], sides["after"]
            median_before = statistics.median(before) if before else float("nan")
            median_after = statistics.median(after) if after else float("nan")
            rows.append({
                "figure": key, "unit": self.units[key],
                "before": before, "after": after,
                "before_median": median_before, "after_median": median_after,
                "before_spread": [min(before, default=float("nan")),
                                  max(before, default=float("nan"))],
                "after_spread": [min(after, default=float("nan")),
                                 max(after, default=float("nan"))],
                "ratio": median_after / median_before if median_before else float("nan"),
                "verdict": (instruction_verdict(before, after)
                            if self.units[key] == "instructions" else verdict(before, after)),
            })  # fmt: skip
        return rows


def _num(value: float) -> str:
    if value != value:
        return "nan"
    if abs(value) >= 100:
        return f"{value:.0f}"
    if abs(value) >= 10:
        return f"{value:.1f}"
    return f"{value:.3f}" if abs(value) < 1 else f"{value:.2f}"


def render_comparison(comparison: Comparison) -> str:
    """One plain-text table: figure, unit, each side's median and min–max, ratio, verdict."""
    header = ("figure", "unit", "before", "before min–max", "after", "after min–max",
              "after/before", "verdict")  # fmt: skip
    lines = [header]
    for row in comparison.rows():
        lines.append((
            row["figure"], row["unit"],
            _num(row["before_median"]), "–".join(_num(v) for v in row["before_spread"]),
            _num(row["after_median"]), "–".join(_num(v) for v in row["after_spread"]),
            f"{row['ratio']:.3f}", row["verdict"],
        ))  # fmt: skip
    widths = [max(len(line[i]) for line in lines) for i in range(len(header))]
    out = []
    for index, line in enumerate(lines):
        out.append("  ".join(c.ljust(w) for c, w in zip(line, widths, strict=True)).rstrip())
        if index == 0:
            out.append("  ".join("-" * w for w in widths))
    return "\n".join(out)


def compare(
    before: Path,
    after: Path,
    names: Sequence[str],
    rounds: int,
    options: dict[str, Any],
    *,
    report: Callable[[str], None] = print,
) -> Comparison:
    """Run every probe of ``names`` ``rounds`` times per tree, B, A, B, A, …; the figures."""
    with tempfile.TemporaryDirectory(prefix="galileo-compare-") as folder:
        work = Path(folder)
        trees = [Tree("before", before.resolve()), Tree("after", after.resolve())]
        server = stage(THIS_CHECKOUT, work / "server")
        for tree in trees:
            tree.commit = git_commit(tree.path)
            tree.staging = stage(tree.path, work / tree.label)
            report(tree.describe())
        report(f"fleet server and frames: {THIS_CHECKOUT} @ {git_commit(THIS_CHECKOUT) or '?'}")
        probe_options = dict(options)
        if "ingest" in names or "instructions" in names:
            from .probe import make_frames

            frames_file = work / "frames.pickle"
            count = max(int(options["frames"]), 3 * max(INSTRUCTION_FRAMES.values()))
            frames_file.write_bytes(pickle.dumps(make_frames(count)))
            probe_options["frames_file"] = str(frames_file)
        comparison = Comparison(trees[0], trees[1])
        envs = {}
        for tree in trees:
            assert tree.staging is not None
            envs[tree.label] = _env(tree.staging, server, work / "pycache")
        for round_ in range(1, rounds + 1):
            for name in names:
                if name == "instructions" and round_ > 1:
                    continue  # the counts repeat: once a tree
                for tree in trees:
                    started = time.monotonic()
                    if name == "instructions":
                        env = {**envs[tree.label], "PYTHONHASHSEED": "0"}
                        figures = instructions(tree, probe_options, env, work)
                    else:
                        figures = run_probe(tree, name, probe_options, envs[tree.label], work)[
                            "figures"
                        ]
                    comparison.add(tree.label, figures)
                    report(f"round {round_}/{rounds} {name} {tree.label}: "
                           f"{time.monotonic() - started:.1f} s")  # fmt: skip
    return comparison


def count_lines(tree: Path) -> dict[str, int]:
    """Modules and lines (all, and non-blank) of ``galileo_async/``; files and lines of tests."""
    counts = {"package modules": 0, "package lines": 0, "package non-blank lines": 0,
              "test files": 0, "test lines": 0}  # fmt: skip
    for folder, prefix in (("galileo_async", "package"), ("tests", "test")):
        for path in sorted((tree / folder).rglob("*.py")):
            if "__pycache__" in path.parts:
                continue
            text = path.read_text(encoding="utf-8", errors="replace").splitlines()
            counts["package modules" if prefix == "package" else "test files"] += 1
            counts[f"{prefix} lines"] += len(text)
            if prefix == "package":
                counts["package non-blank lines"] += sum(1 for line in text if line.strip())
    return counts


def _lines(before: Path, after: Path) -> int:
    counts = {"before": count_lines(before), "after": count_lines(after)}
    print(f"before: {before} @ {git_commit(before) or '?'}")
    print(f"after:  {after} @ {git_commit(after) or '?'}\n")
    header = ("", "before", "after", "change")
    lines = [header]
    for key in counts["before"]:
        old, new = counts["before"][key], counts["after"][key]
        lines.append((key, f"{old:,}", f"{new:,}", f"{new - old:+,}"))
    widths = [max(len(line[i]) for line in lines) for i in range(len(header))]
    for line in lines:
        print("  ".join(c.rjust(w) if i else c.ljust(w)
                        for i, (c, w) in enumerate(zip(line, widths, strict=True))))  # fmt: skip
    return 0


def main(argv: list[str]) -> int:
    """``compare …`` or ``lines …`` (argv without the program name)."""
    command, rest = argv[0], argv[1:]
    parser = argparse.ArgumentParser(prog=f"python -m benchmarks {command}", description=__doc__)
    parser.add_argument("--before", type=Path, required=True, help="the tree before the change")
    parser.add_argument("--after", type=Path, default=THIS_CHECKOUT,
                        help="the tree after the change (default: this checkout)")  # fmt: skip
    if command == "lines":
        args = parser.parse_args(rest)
        return _lines(args.before, args.after)
    every = ", ".join(PROBE_NAMES)
    parser.add_argument("names", nargs="*", choices=[*PROBE_NAMES, *EXTRA_NAMES, []],
                        metavar="NAME", help=f"probes to run (default: all of {every}; "
                        "instructions: ingest under cachegrind, once a tree)")  # fmt: skip
    parser.add_argument("--rounds", type=int, default=None,
                        help="runs per tree and probe (default 5, --quick 3)")  # fmt: skip
    parser.add_argument("--quick", action="store_true", help="fewer samples, shorter windows")
    parser.add_argument("--fleet", type=int, default=None, help="fleet size (default 1000)")
    parser.add_argument("--json", type=Path, default=None, help="where to write the results")
    args = parser.parse_args(rest)
    names = args.names or list(PROBE_NAMES)
    rounds = args.rounds or (3 if args.quick else 5)
    options = dict(QUICK if args.quick else FULL)
    if args.fleet is not None:
        options["fleet"] = args.fleet
    info = machine()
    print(f"{info['date']}  {info['cpu']}  nproc={info['nproc']}  Python {info['python']}  "
          f"load {info['loadavg']}", flush=True)  # fmt: skip
    started = time.monotonic()
    comparison = compare(args.before, args.after, names, rounds, options,
                         report=lambda line: print(line, flush=True))  # fmt: skip
    elapsed = time.monotonic() - started
    finished = machine()
    print()
    print(render_comparison(comparison))
    print(f"\n{rounds} round(s) per tree, {elapsed:.0f} s; load at the start "
          f"{info['loadavg']}, at the end {finished['loadavg']}")  # fmt: skip
    path = args.json or RESULTS / time.strftime("compare-%Y%m%d-%H%M%S.json", time.gmtime())
    path.parent.mkdir(parents=True, exist_ok=True)
    result = {
        "machine": info,
        "load_at_end": finished["loadavg"],
        "quick": args.quick,
        "rounds": rounds,
        "options": options,
        "seconds": round(elapsed, 1),
        "trees": {
            tree.label: {"path": str(tree.path), "commit": tree.commit}
            for tree in (comparison.before, comparison.after)
        },
        "rows": comparison.rows(),
    }
    path.write_text(json.dumps(result, indent=2, default=str) + "\n")
    print(f"written to {path}")
    return 0
