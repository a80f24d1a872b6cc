"""One shape per kind of JSON line: status lines and event lines, as docs/cli.md shows them."""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

import pytest

from galileo_async.cli import ExitCode
from tests.cli.test_cli import DROPPING, FAST, invoke, json_lines
from tests.support.ports import refused_port

ROOT = Path(__file__).resolve().parents[2]
#: The extra keys of a fleet status line: which robot, its state (before it connects too)
#: and its last event.
FLEET_KEYS = {"name", "state", "last_event"}


def shape(line: dict[str, Any]) -> dict[str, Any]:
    """A line's keys, and for an object value (status, link) the keys of that object."""
    return {
        key: sorted(value) if isinstance(value, dict) else type(value).__name__
        for key, value in line.items()
    }


def keys_and_nesting(line: dict[str, Any]) -> dict[str, Any]:
    """shape() without the types of plain values (a number may be an int or a float)."""
    return {
        key: value if isinstance(value, list) else "value" for key, value in shape(line).items()
    }


def documented(kind: str) -> dict[str, Any]:
    """The example line of ``kind`` of docs/cli.md's "JSON lines": ``<!-- json: kind -->``."""
    text = (ROOT / "docs" / "cli.md").read_text(encoding="utf-8")
    match = re.search(rf"<!-- json: {kind} -->\n```json\n(.*?)\n```", text, re.S)
    assert match, f"docs/cli.md has no example of a {kind} line"
    data: dict[str, Any] = json.loads(match.group(1))
    return data


@pytest.fixture(scope="module")
def status_lines(tmp_path_factory: pytest.TempPathFactory) -> dict[str, list[dict[str, Any]]]:
    """The status lines of each command that prints them, by command."""
    once = invoke("--json", "status")
    watch = invoke("--json", "status", "--watch", "--count", "2", "--interval", "0.05")
    monitor = invoke("--json", "monitor", "--duration", "2.5")
    fleet_file = tmp_path_factory.mktemp("fleet") / "fleet.toml"
    fleet_file.write_text(f'[robots.alpha]\nport = "{FAST}"\n')
    fleet = invoke("--fleet", str(fleet_file), "fleet", "status", "--json", port=None)
    for result in (once, watch, monitor, fleet):
        assert result.exit_code == ExitCode.OK, result.output
    return {
        "status": json_lines(once.stdout),
        "status --watch": json_lines(watch.stdout),
        "monitor": [line for line in json_lines(monitor.stdout) if "event" not in line],
        "fleet status": json_lines(fleet.stdout),
    }


def test_status_lines_have_one_shape(status_lines: dict[str, list[dict[str, Any]]]) -> None:
    (once,) = status_lines["status"]
    expected = keys_and_nesting(once)
    assert list(once)[:2] == ["port", "time"]
    assert set(once) == {"port", "time", "status", "link"}
    for command in ("status --watch", "monitor"):
        lines = status_lines[command]
        assert lines, command
        for line in lines:
            assert keys_and_nesting(line) == expected, command
            assert list(line) == list(once), command  # the same order too
    (fleet,) = status_lines["fleet status"]
    assert set(fleet) == set(once) | FLEET_KEYS
    assert {key: keys_and_nesting(fleet)[key] for key in once} == expected
    assert fleet["name"] == "alpha"
    assert fleet["port"] == FAST
    assert fleet["state"] == fleet["link"]["state"] == "up"


def test_status_lines_are_as_documented(status_lines: dict[str, list[dict[str, Any]]]) -> None:
    (once,) = status_lines["status"]
    assert keys_and_nesting(documented("status")) == keys_and_nesting(once)
    assert list(documented("status")) == list(once)
    (fleet,) = status_lines["fleet status"]
    example = documented("fleet status")  # a robot that never connected: no status, no link
    assert list(example) == list(fleet)
    assert example["status"] is None
    assert example["link"] is None


def test_a_robot_that_never_connected_has_a_status_line_too(tmp_path: Path) -> None:
    fleet_file = tmp_path / "fleet.toml"
    with refused_port() as port:
        fleet_file.write_text(f'[robots.gone]\nport = "socket://127.0.0.1:{port}"\n')
        result = invoke("--fleet", str(fleet_file), "--json", "fleet", "status", port=None)
    assert result.exit_code == ExitCode.CONNECTION, result.output
    (line,) = json_lines(result.stdout)
    assert set(line) == {"port", "time", "status", "link"} | FLEET_KEYS
    assert line["status"] is None
    assert line["link"] is None
    assert line["state"] == "lost"
    assert line["last_event"].startswith("connect failed: ")


def test_event_lines_have_one_shape() -> None:
    watch = invoke("--json", "status", "--watch", "--count", "10", "--interval", "0.05",
                   port=DROPPING)  # fmt: skip
    monitor = invoke("--json", "monitor", "--duration", "3", port=DROPPING)
    shapes: dict[str, dict[str, list[dict[str, Any]]]] = {}
    for command, result in (("status --watch", watch), ("monitor", monitor)):
        assert result.exit_code == ExitCode.OK, result.output
        for line in json_lines(result.stdout):
            if "event" in line:
                shapes.setdefault(line["event"], {}).setdefault(command, []).append(
                    keys_and_nesting(line)
                )
    both = {name: seen for name, seen in shapes.items() if len(seen) == 2}
    assert "ConnectionLost" in both
    for name, seen in both.items():
        first = seen["status --watch"][0]
        assert all(found == first for found in seen["monitor"]), name
    documented_line = documented("event")
    lost = both["ConnectionLost"]["monitor"][0]
    assert keys_and_nesting(documented_line) == lost
