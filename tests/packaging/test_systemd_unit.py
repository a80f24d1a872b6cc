"""docs/galileo-vda5050.service: the unit docs/cli.md gives for running ``galileo vda5050``.

Parsed here (sections, keys, its command line by galileo's own parser), and verified by
``systemd-analyze verify`` where systemd is installed.
"""

from __future__ import annotations

import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import typer.main

from galileo_async.cli import ExitCode, app
from galileo_async.cli.vda5050 import PASSWORD_ENV
from galileo_async.vda5050 import VehicleConfig, parse_broker_url
from galileo_async.vda5050.session import LAST_WORDS_TIMEOUT, OFFLINE_TIMEOUT
from galileo_async.vda5050.shutdown import SHUTDOWN_TIMEOUT
from tests.support.peers import missing_peer

UNIT = Path(__file__).resolve().parents[2] / "docs" / "galileo-vda5050.service"
#: Keys a unit may give more than once (each adds to the list).
REPEATABLE = {"Wants", "After", "Environment", "EnvironmentFile", "SupplementaryGroups"}


def parse_unit(text: str) -> dict[str, dict[str, str]]:
    """Sections of a systemd unit file, each key's value (continued lines joined)."""
    sections: dict[str, dict[str, str]] = {}
    section: dict[str, str] | None = None
    pending = ""
    for number, raw in enumerate(text.splitlines(), 1):
        line = pending + raw.strip()
        pending = ""
        if not line or line.startswith(("#", ";")):
            continue
        if line.endswith("\\"):
            pending = line[:-1] + " "
            continue
        if line.startswith("[") and line.endswith("]"):
            name = line[1:-1]
            assert name not in sections, f"line {number}: [{name}] twice"
            section = sections[name] = {}
            continue
        key, equals, value = line.partition("=")
        assert equals, f"line {number}: neither a section nor key=value: {raw!r}"
        assert section is not None, f"line {number}: {key} before any section"
        key, value = key.strip(), value.strip()
        assert key not in section or key in REPEATABLE, f"line {number}: {key} twice"
        section[key] = f"{section[key]} {value}" if key in section else value
    assert not pending, "the last line continues"
    return sections


@pytest.fixture(name="unit")
def unit_fixture() -> dict[str, dict[str, str]]:
    return parse_unit(UNIT.read_text(encoding="utf-8"))


def test_the_unit_stops_the_adapter_cleanly_and_restarts_it_on_failure(
    unit: dict[str, dict[str, str]],
) -> None:
    assert set(unit) == {"Unit", "Service", "Install"}
    service = unit["Service"]
    assert service["KillSignal"] == "SIGTERM"
    # SIGKILL before the clean stop is done would leave the last will instead of OFFLINE.
    stop_takes = SHUTDOWN_TIMEOUT + 2 * OFFLINE_TIMEOUT
    assert float(service["TimeoutStopSec"]) > stop_takes
    assert LAST_WORDS_TIMEOUT > SHUTDOWN_TIMEOUT + OFFLINE_TIMEOUT
    assert service["Restart"] == "on-failure"
    prevented = service["RestartPreventExitStatus"].split()
    assert str(int(ExitCode.USAGE)) in prevented
    assert str(int(ExitCode.DUPLICATE_VEHICLE)) in prevented
    assert Path(service["EnvironmentFile"]).is_absolute()
    assert PASSWORD_ENV in UNIT.read_text(encoding="utf-8")  # what goes in that file
    assert unit["Install"]["WantedBy"] == "multi-user.target"


def test_its_command_line_parses_with_galileos_own_parser(
    unit: dict[str, dict[str, str]],
) -> None:
    argv = shlex.split(unit["Service"]["ExecStart"])
    assert Path(argv[0]).is_absolute()
    assert Path(argv[0]).name == "galileo"
    group = typer.main.get_command(app)
    context = group.make_context("galileo", argv[1:])
    assert context.params["port"]
    name = argv[len(argv) - len(context.args) - 1]
    assert name == "vda5050"
    _, command, rest = group.resolve_command(context, [name, *context.args])
    assert command is not None
    params = command.make_context(name, rest, parent=context).params
    [broker] = params["broker"]  # --broker may be repeated; the unit names one
    # The password comes from the EnvironmentFile, never the command line.
    assert parse_broker_url(broker).password is None
    assert params["password_file"] is None
    config = VehicleConfig(
        broker=broker,
        manufacturer=params["manufacturer"],
        serial_number=params["serial_number"],
        password="from the environment file",
    )
    assert config.topic("state").endswith(f"/{params['manufacturer']}/7/state")


def test_systemd_analyze_verifies_the_unit(tmp_path: Path) -> None:
    tool = shutil.which("systemd-analyze")
    if tool is None:
        missing_peer("systemd-analyze (Debian's systemd)")
        return
    # verify wants ExecStart's program to exist: this checkout's galileo stands in for it.
    program = tmp_path / "galileo"
    program.write_text(f'#!/bin/sh\nexec {shlex.quote(sys.executable)} -m galileo_async "$@"\n')
    program.chmod(0o755)
    text = UNIT.read_text(encoding="utf-8")
    installed = shlex.split(parse_unit(text)["Service"]["ExecStart"])[0]
    assert text.count(f"ExecStart={installed} ") == 1
    copy = tmp_path / UNIT.name
    copy.write_text(text.replace(f"ExecStart={installed} ", f"ExecStart={program} "))
    result = subprocess.run(
        [tool, "verify", "--man=no", str(copy)], capture_output=True, text=True, timeout=120
    )
    complaints = [line for line in result.stderr.splitlines() if UNIT.name in line]
    assert result.returncode == 0, result.stderr
    assert complaints == [], result.stderr


def test_docs_show_the_units_lines_as_they_are() -> None:
    cli = (UNIT.parent / "cli.md").read_text(encoding="utf-8")
    section = cli[cli.index("## Running the adapter under systemd") :]
    block = section[section.index("```ini\n") + len("```ini\n") : section.index("\n```")]
    unit = parse_unit(UNIT.read_text(encoding="utf-8"))
    shown = parse_unit(block)
    for name, keys in shown.items():
        for key, value in keys.items():
            assert unit[name][key] == value, (name, key)
