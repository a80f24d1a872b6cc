"""``galileo --fleet FILE fleet status|monitor`` and the monitor's map options, in-process."""

from __future__ import annotations

import json
import socket
from pathlib import Path

from typer.testing import CliRunner, Result

from galileo_async.cli import ExitCode, app

FLEET = """
[defaults]
first_status_timeout = 5

[robots.alpha]
port = "sim://?speed=20"

[robots.beta]
port = "sim://?speed=20"

[robots.down]
port = "{dead}"
connect_timeout = 2
"""


def invoke(*args: str) -> Result:
    env = {"GALILEO_PORT": None, "GALILEO_FLEET": None, "COLUMNS": "140"}
    return CliRunner().invoke(app, list(args), env=env)


def fleet_file(tmp_path: Path) -> str:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        dead = f"socket://127.0.0.1:{probe.getsockname()[1]}"
    path = tmp_path / "fleet.toml"
    path.write_text(FLEET.format(dead=dead))
    return str(path)


def test_fleet_status_json_has_a_row_per_robot(tmp_path: Path) -> None:
    result = invoke("--fleet", fleet_file(tmp_path), "--json", "fleet", "status", "--sort", "state")
    assert result.exit_code == ExitCode.CONNECTION, result.output  # one robot is down
    rows = [json.loads(line) for line in result.stdout.splitlines()]
    assert [(row["name"], row["state"]) for row in rows] == [
        ("alpha", "up"), ("beta", "up"), ("down", "lost"),
    ]  # fmt: skip
    assert rows[0]["status"]["power"] > 0
    assert rows[2]["status"] is None
    assert rows[2]["last_event"].startswith("connect failed")


def test_fleet_status_filters(tmp_path: Path) -> None:
    path = fleet_file(tmp_path)
    result = invoke("--fleet", path, "--json", "fleet", "status", "--state", "lost")
    assert [json.loads(line)["name"] for line in result.stdout.splitlines()] == ["down"]
    result = invoke("--fleet", path, "--json", "fleet", "status", "--match", "ta")
    assert [json.loads(line)["name"] for line in result.stdout.splitlines()] == ["beta"]
    table = invoke("--fleet", path, "fleet", "status")
    assert "up 2" in table.stdout
    assert "lost 1" in table.stdout


def test_fleet_monitor_runs_and_writes_svg(tmp_path: Path) -> None:
    svg = tmp_path / "fleet.svg"
    result = invoke("--fleet", fleet_file(tmp_path), "fleet", "monitor", "--duration", "0.6",
                    "--svg", str(svg))  # fmt: skip
    assert result.exit_code == 0, result.output
    for text in ("galileo fleet", "3 robots", "goals running 0", "alpha", "─ map ─", "◆0"):
        assert text in result.stdout, text
    assert svg.read_text().startswith("<svg")


def test_fleet_usage_errors(tmp_path: Path) -> None:
    result = invoke("fleet", "status")
    assert result.exit_code == ExitCode.USAGE
    assert "--fleet" in result.stderr
    bad = tmp_path / "bad.toml"
    bad.write_text('[robots.r2]\nport = "sim://"\nmap_targets = "x"\n')
    result = invoke("--fleet", str(bad), "fleet", "status")
    assert result.exit_code == ExitCode.USAGE
    assert "robot 'r2': map_targets" in result.stderr
    path = fleet_file(tmp_path)
    for option, value in (("--sort", "colour"), ("--state", "asleep")):
        result = invoke("--fleet", path, "fleet", "monitor", option, value)
        assert result.exit_code == ExitCode.USAGE, (option, result.output)


def test_monitor_map_targets_and_svg(tmp_path: Path) -> None:
    targets = tmp_path / "targets.csv"
    targets.write_text("40,1.0,1.0\n")
    svg = tmp_path / "monitor.svg"
    result = invoke("--port", "sim://?speed=20", "monitor", "--duration", "0.3",
                    "--targets", str(targets), "--svg", str(svg))  # fmt: skip
    assert result.exit_code == 0, result.output
    assert "◆40" in result.stdout
    assert "◆5" in result.stdout  # the simulator's own map
    assert "galileo" in svg.read_text()
    targets.write_text("40,1.0\n")
    result = invoke("monitor", "--duration", "0.3", "--targets", str(targets))
    assert result.exit_code == ExitCode.USAGE
    assert "expected 3 columns" in result.stderr
