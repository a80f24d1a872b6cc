"""``python -m benchmarks compare``: its verdicts, its table, and a real round on two trees."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest

from benchmarks import probe
from benchmarks.compare import (
    THIS_CHECKOUT,
    Comparison,
    Tree,
    _env,
    compare,
    count_lines,
    instruction_verdict,
    main,
    render_comparison,
    run_probe,
    stage,
    verdict,
)
from tests.support.peers import missing_peer

#: A round small enough for a test: what matters is that every probe runs, not its figures.
TINY = {"frames": 200, "repeats": 1, "path_frames": 50, "samples": 20, "ros_samples": 10,
        "fleet": 4, "seconds": 0.2, "warmup": 0.1, "server_warmup": 0.1}  # fmt: skip


@pytest.mark.parametrize(
    ("before", "after", "expected"),
    [
        ([10.0, 11.0, 12.0], [10.5, 11.5, 12.5], "within spread"),
        ([10.0, 11.0, 12.0], [14.0, 14.5, 15.0], "slower"),
        ([10.0, 11.0, 12.0], [7.0, 7.5, 8.0], "faster"),
        # Above the before side's max, but by less than the spread: not slower.
        ([10.0, 10.1, 10.2], [11.0, 11.5, 14.0], "within spread"),
        # Beyond the spread of either side, but not above the before side's max.
        ([10.0, 10.1, 20.0], [10.2, 10.3, 10.35], "within spread"),
        ([10.0], [20.0], "n/a"),
        ([10.0, 10.0], [10.0, 10.0], "within spread"),
        ([10.0, 10.0], [10.1, 10.1], "slower"),
        ([float("nan")], [float("nan")], "not run"),
        ([float("nan"), float("nan")], [float("nan"), float("nan")], "not run"),
    ],
)
def test_verdict_slower_only_above_the_before_max_by_more_than_the_spread(
    before: list[float], after: list[float], expected: str
) -> None:
    assert verdict(before, after) == expected


@pytest.mark.parametrize(
    ("before", "after", "expected"),
    [
        ([18552.0], [18572.0], "within spread"),
        ([18552.0], [18800.0], "slower"),
        ([18552.0], [18300.0], "faster"),
        ([], [18300.0], "n/a"),
    ],
)
def test_instruction_counts_repeat_so_one_per_side_has_a_verdict(
    before: list[float], after: list[float], expected: str
) -> None:
    assert instruction_verdict(before, after) == expected


def test_instruction_figures_take_the_instruction_verdict() -> None:
    comparison = Comparison(Tree("before", Path("/b")), Tree("after", Path("/a")))
    comparison.add("before", {"x": [100.0, "instructions"], "y": [100.0, "µs"]})
    comparison.add("after", {"x": [120.0, "instructions"], "y": [120.0, "µs"]})
    verdicts = {row["figure"]: row["verdict"] for row in comparison.rows()}
    assert verdicts == {"x": "slower", "y": "n/a"}


def test_the_table_shows_medians_spreads_ratio_and_verdict_per_figure() -> None:
    comparison = Comparison(Tree("before", Path("/b")), Tree("after", Path("/a")))
    for before, after in ((2.0, 4.0), (3.0, 5.0), (4.0, 6.0)):
        comparison.add("before", {"ingest x": [before, "µs"], "latency y": [1.0, "ms"]})
        comparison.add("after", {"ingest x": [after, "µs"], "latency y": [1.0, "ms"]})
    rows = {row["figure"]: row for row in comparison.rows()}
    assert rows["ingest x"]["before_median"] == 3.0
    assert rows["ingest x"]["after_median"] == 5.0
    assert rows["ingest x"]["before_spread"] == [2.0, 4.0]
    assert rows["ingest x"]["ratio"] == pytest.approx(5 / 3)
    assert rows["ingest x"]["verdict"] == "within spread"
    assert rows["latency y"]["ratio"] == 1.0
    table = render_comparison(comparison).splitlines()
    assert table[0].split() == ["figure", "unit", "before", "before", "min–max", "after",
                                "after", "min–max", "after/before", "verdict"]  # fmt: skip
    assert table[2].split() == ["ingest", "x", "µs", "3.00", "2.00–4.00", "5.00", "4.00–6.00",
                                "1.667", "within", "spread"]  # fmt: skip
    assert table[3].split()[-2:] == ["within", "spread"]
    assert len(table) == 4


def test_lines_counts_modules_and_lines_of_package_and_tests(tmp_path: Path) -> None:
    (tmp_path / "galileo_async" / "sub").mkdir(parents=True)
    (tmp_path / "galileo_async" / "__init__.py").write_text("x = 1\n\ny = 2\n")
    (tmp_path / "galileo_async" / "sub" / "a.py").write_text("z = 3\n")
    (tmp_path / "galileo_async" / "__pycache__").mkdir()
    (tmp_path / "galileo_async" / "__pycache__" / "stale.py").write_text("old = 1\n")
    (tmp_path / "tests").mkdir()
    (tmp_path / "tests" / "test_a.py").write_text("def test() -> None:\n    pass\n")
    assert count_lines(tmp_path) == {
        "package modules": 2, "package lines": 4, "package non-blank lines": 3,
        "test files": 1, "test lines": 2,
    }  # fmt: skip


def test_lines_command_prints_both_trees(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["lines", "--before", str(THIS_CHECKOUT), "--after", str(THIS_CHECKOUT)]) == 0
    out = capsys.readouterr().out
    assert "package modules" in out
    assert "+0" in out


def test_a_probe_that_imports_another_trees_package_is_refused(tmp_path: Path) -> None:
    other = tmp_path / "other"
    (other / "galileo_async").mkdir(parents=True)
    (other / "galileo_async" / "__init__.py").write_text("")
    # The probe runs on this checkout's package while the tree claims to be ``other``.
    env = _env(stage(THIS_CHECKOUT, tmp_path / "staged"), tmp_path / "staged", tmp_path / "pyc")
    work = tmp_path / "work"
    work.mkdir()
    with pytest.raises(RuntimeError, match="imported"):
        run_probe(Tree("before", other), "latency", {"samples": 8, "ros_samples": 4}, env, work)


def test_a_real_tiny_round_runs_every_probe_on_two_trees() -> None:
    lines: list[str] = []
    comparison = compare(THIS_CHECKOUT, THIS_CHECKOUT, ["ingest", "latency", "fleet"], 1,
                         TINY, report=lines.append)  # fmt: skip
    assert lines[0].startswith(f"before: {THIS_CHECKOUT} @ ")
    assert lines[1].startswith(f"after: {THIS_CHECKOUT} @ ")
    order = [line.split(":")[0] for line in lines if line.startswith("round")]
    assert order == [f"round 1/1 {name} {side}" for name in ("ingest", "latency", "fleet")
                     for side in ("before", "after")]  # fmt: skip
    rows = comparison.rows()
    figures = [row["figure"] for row in rows]
    for scheme in ("socket://", "udp://", "http://"):
        assert sum(figure.startswith(f"latency {scheme}") for figure in figures) == 4
    assert any(figure.startswith("ingest:") for figure in figures)
    assert any(figure.startswith("fleet N=4:") for figure in figures)
    ros = [row for row in rows if row["figure"].startswith("latency ros://")]
    measured = [row for row in rows if row not in ros]
    if _ros_installed():
        assert [row["figure"] for row in ros] == [
            "latency ros:// status published → wait_until p50",
            "latency ros:// status published → wait_until p99",
            "latency ros:// robot.forward() → rospy callback at node p50",
            "latency ros:// robot.forward() → rospy callback at node p99",
        ]
        measured += ros
    for row in measured:
        assert len(row["before"]) == len(row["after"]) == 1, row
        assert row["before_median"] > 0, row
        assert row["after_median"] > 0, row
        assert row["verdict"] == "n/a"
    assert len(render_comparison(comparison).splitlines()) == len(rows) + 2
    if not _ros_installed():
        assert [(row["figure"].split(":")[0], row["verdict"]) for row in ros] == [
            ("latency ros:// not run", "not run")
        ]
        missing_peer("ROS 1")  # the other links were measured; ros:// was not


def _ros_installed() -> bool:
    return shutil.which("rosmaster") is not None and os.access(probe.SYSTEM_PYTHON, os.X_OK)


def test_a_link_whose_peer_is_missing_gives_a_not_run_figure(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setattr(shutil, "which", lambda name: None)
    ros = [link for link in probe.LINKS if link[0] == "ros://"]
    assert len(ros) == 1
    monkeypatch.setattr(probe, "LINKS", tuple(ros))
    figures = probe.latency({"ros_samples": 5})
    assert list(figures) == [
        "latency ros:// not run: ROS 1 (rosmaster, rospy) is not installed: run .ci/setup (as root)"
    ]
    value, unit = next(iter(figures.values()))
    assert value != value  # NaN: no number stands in for a measurement
    assert unit == ""
    comparison = Comparison(Tree("before", Path("/b")), Tree("after", Path("/a")))
    for side in ("before", "after"):
        comparison.add(side, {key: [value, unit] for key, (value, unit) in figures.items()})
    assert [row["verdict"] for row in comparison.rows()] == ["not run"]
    assert "not run" in render_comparison(comparison)


def test_a_probe_imports_its_trees_package_and_writes_no_bytecode_into_it(
    tmp_path: Path,
) -> None:
    tree = tmp_path / "tree"
    shutil.copytree(THIS_CHECKOUT / "galileo_async", tree / "galileo_async",
                    ignore=shutil.ignore_patterns("__pycache__"))  # fmt: skip
    env = _env(stage(tree, tmp_path / "staged"), tmp_path / "staged", tmp_path / "pyc")
    env.pop("PYTHONDONTWRITEBYTECODE", None)  # bytecode is written, but not into the tree
    work = tmp_path / "work"
    work.mkdir()
    result = run_probe(Tree("after", tree), "latency", {"samples": 8, "ros_samples": 4}, env, work)
    assert Path(result["package"]).is_relative_to(tree / "galileo_async")
    assert not list(tree.rglob("__pycache__"))
    assert list((tmp_path / "pyc").rglob("*.pyc"))
