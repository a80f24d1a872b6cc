"""Every example runs as is against the embedded simulator (sped up through GALILEO_PORT)."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
FAST_SIM = "sim://?speed=20"
#: Real seconds any example may take at 20x.
TIMEOUT = 60


def run_example(name: str, *args: str) -> str:
    env = dict(os.environ, GALILEO_PORT=FAST_SIM)
    result = subprocess.run(
        [sys.executable, str(EXAMPLES / name), *args],
        capture_output=True, text=True, timeout=TIMEOUT, env=env, check=False,
    )  # fmt: skip
    assert result.returncode == 0, result.stdout + result.stderr
    assert "Traceback" not in result.stderr
    return result.stdout


def test_every_example_is_tested() -> None:
    # vda5050_vehicle.py needs a broker: tests/vda5050/test_vda5050_links.py runs it.
    # test_patrol_app.py is a pytest file: tests/testing/test_testing_example.py runs it.
    tested = {
        "goto.py", "patrol.py", "monitor.py", "teleop.py", "fleet.py", "fleet_dashboard.py",
        "vda5050_vehicle.py", "http_maps.py", "patrol_app.py", "test_patrol_app.py",
        "mission.py", "foxglove_view.py", "record_mcap.py", "metrics.py",
    }  # fmt: skip
    assert {path.name for path in EXAMPLES.glob("*.py")} == tested


def test_foxglove_view_example_serves_two_touring_robots() -> None:
    out = run_example("foxglove_view.py", "4", "0")
    assert re.search(r"open ws://127\.0\.0\.1:\d+ in Foxglove or Lichtblick", out), out
    assert "alpha: arrived at" in out
    assert "beta: arrived at" in out


def test_record_mcap_example_records_a_goal_and_reads_it_back(tmp_path: Path) -> None:
    path = tmp_path / "drive.mcap"
    out = run_example("record_mcap.py", FAST_SIM, str(path))
    assert path.read_bytes().startswith(b"\x89MCAP0\r\n")
    assert f"{path}: " in out
    assert "GoalAccepted target_id=1" in out
    assert "GoalReached target_id=1" in out


def test_http_maps_example_lists_maps_and_goes_to_a_pose() -> None:
    out = run_example("http_maps.py")
    assert "firmware 5.1.0" in out
    assert "maps: sim, floor2" in out
    assert "current map: sim, path path1" in out
    assert "target 0: (" in out
    assert "arrived at (1.0, 0.5)" in out


def test_mission_example_checks_then_runs_two_laps() -> None:
    out = run_example("mission.py")
    assert "check:" not in out  # nothing wrong with the plan on the simulator
    assert out.count("steps[0].loop.steps[0] goto: reached") == 2
    assert out.count("dwell: done") == 2
    assert "steps[1] goto: reached" in out
    assert "mission 'two-lap patrol': completed, 2 laps" in out


def test_metrics_example_serves_what_the_robot_did() -> None:
    out = run_example("metrics.py", FAST_SIM, "0")  # port 0: a free one
    assert "serving http://127.0.0.1:" in out
    assert 'galileo_goals_ended_total{ending="reached",robot="robot1"} 2.0' in out
    driven = [line for line in out.splitlines() if line.startswith("galileo_odometer")]
    assert float(driven[0].split()[-1]) > 1.0
    assert 'galileo_battery_volts{robot="robot1"}' in out


def test_goto_example_handles_arrival_and_rejection() -> None:
    out = run_example("goto.py")
    assert "arrived at 1" in out
    assert "arrived at 2" in out
    assert "goal 42 rejected" in out


def test_patrol_example_visits_three_targets_and_keeps_navigation() -> None:
    out = run_example("patrol.py")
    assert out.count("reached target") == 3
    assert "navigation still open: True" in out


def test_patrol_app_example_does_two_laps() -> None:
    out = run_example("patrol_app.py")
    assert out.count("reached") == 6
    assert "visited [1, 2, 3, 1, 2, 3], skipped [], 2 laps" in out


def test_monitor_example_sees_statuses_and_events() -> None:
    out = run_example("monitor.py", FAST_SIM, "30")
    assert "target 0 working" in out
    assert "target 0 free" in out
    for event in ("NavigationOpened", "VisualInitialised", "GoalAccepted", "GoalReached"):
        assert f"event: {event}" in out


def test_teleop_example_drives_and_stops() -> None:
    out = run_example("teleop.py")
    assert "forward: +0.40 m/s" in out
    assert "arc: +0.40 m/s, +0.60 rad/s" in out  # the linear speed kept while turning
    assert "turn on the spot: -0.90 rad/s" in out  # to the right
    assert "stopped at" in out


@pytest.mark.parametrize("urls", [(), (FAST_SIM + "&layout=v1", FAST_SIM + "&layout=v2_truncated")])
def test_fleet_example_drives_robots_concurrently(urls: tuple[str, ...]) -> None:
    out = run_example("fleet.py", *urls)
    robots = len(urls) or 3
    assert out.count("finished its tour") == robots
    assert out.count("arrived at") == 3 * robots


def test_fleet_dashboard_example_uses_one_merged_stream() -> None:
    out = run_example("fleet_dashboard.py", "3")
    assert "3 robots: robot-0, robot-1, robot-2" in out
    for number in range(3):
        assert f"robot-{number}: arrived at {number}" in out
        assert f"robot-{number}: event GoalReached" in out
        assert f"robot-{number}: pose unknown target -1" in out  # the first merged statuses
