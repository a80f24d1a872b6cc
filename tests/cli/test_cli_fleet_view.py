"""The fleet view names each field by its own enum, counts running goals, fits 80 columns."""

from __future__ import annotations

import json
import re
import socket
import subprocess
import sys
from pathlib import Path

import pytest

from galileo_async import connect_fleet
from galileo_async.cli import ExitCode
from galileo_async.cli.fleet_view import (
    COLUMNS,
    DROP_ORDER,
    FleetRow,
    FleetView,
    fleet_rows,
    row_cells,
    summary_line,
)  # fmt: skip
from galileo_async.cli.map_model import MapModel
from galileo_async.models import ChargeStatus, LinkState, NavStatus, TargetStatus, VisualStatus
from tests.cli.test_cli_monitor_small import tmux  # noqa: F401
from tests.support.fake_device import make_status
from tests.support.tmux_support import keys, until

SIM = "sim://?speed=20"
#: Fields set to the first member of every other enum, so a name cached by value shows up.
OTHERS = {
    "nav_status": NavStatus.OPEN,
    "visual_status": VisualStatus.TRACKING,
    "charge_status": ChargeStatus.CHARGING,
    "target_status": TargetStatus.WORKING,
}


async def _row(**fields: object) -> FleetRow:
    async with connect_fleet({"r": SIM}) as fleet:
        for field, value in OTHERS.items():  # warm any cache with every other enum's names
            fleet_rows(fleet, {"r": make_status(**{field: value})}, {})
        (row,) = fleet_rows(fleet, {"r": make_status(target_num_id=2, **fields)}, {})
    return row


@pytest.mark.parametrize("member", list(NavStatus))
async def test_nav_is_named_by_nav_status(member: NavStatus) -> None:
    assert (await _row(nav_status=member)).nav == member.name.lower()


@pytest.mark.parametrize("member", list(VisualStatus))
async def test_visual_is_named_by_visual_status(member: VisualStatus) -> None:
    assert (await _row(visual_status=member)).visual == member.name.lower()


@pytest.mark.parametrize("member", list(ChargeStatus))
async def test_charge_is_named_by_charge_status(member: ChargeStatus) -> None:
    row = await _row(charge_status=member)
    assert row.charge == row_cells(row)["charge"] == member.name.lower()


@pytest.mark.parametrize("member", list(TargetStatus))
async def test_goal_is_named_by_target_status(member: TargetStatus) -> None:
    row = await _row(target_status=member)
    assert row.goal_state == member.name.lower()
    assert row_cells(row)["goal"] == f"2 {member.name.lower()}"
    running = 1 if member is TargetStatus.WORKING else 0
    assert summary_line([row]).endswith(f"goals running {running}")


def _plain(state: LinkState) -> FleetRow:
    return FleetRow("r", state, None, "—", "—", "—", None, "—", None, None, None, None, None, "")


@pytest.mark.parametrize("state", list(LinkState))
def test_link_is_named_by_link_state(state: LinkState) -> None:
    row = _plain(state)
    assert str(row_cells(row)["link"]) == state.value
    assert summary_line([row, _plain(LinkState.UP)]).startswith("2 robots ·")
    assert f"{state.value} {2 if state is LinkState.UP else 1}" in summary_line(
        [row, _plain(LinkState.UP)]
    )


async def test_a_closed_robot_shows_closed() -> None:
    async with connect_fleet({"r": SIM}) as fleet:
        pass
    (row,) = fleet_rows(fleet, {}, {})
    assert row.state is LinkState.CLOSED
    assert str(row_cells(row)["link"]) == "closed"


async def test_80_columns_drop_the_least_important_columns_first() -> None:
    async with connect_fleet({"alpha": SIM}) as fleet:
        view = FleetView(fleet, MapModel(), width=80)
        view.latest = {"alpha": make_status(target_num_id=3, target_status=TargetStatus.WORKING)}
        view.events = {"alpha": "goal 3 started, a long event text to be cut"}
        headers = [column.header for column in view.table().renderable.columns]  # type: ignore[union-attr]
        wide = FleetView(fleet, MapModel(), width=200)
        wide.latest = view.latest
        every = [column.header for column in wide.table().renderable.columns]  # type: ignore[union-attr]
    assert every == list(COLUMNS)
    dropped = [column for column in COLUMNS if column not in headers]
    assert dropped  # 80 columns do not hold them all
    assert set(dropped) == set(DROP_ORDER[: len(dropped)])
    assert {"robot", "link", "goal"} <= set(headers)


FLEET = """
[defaults]
first_status_timeout = 5

[robots.alpha]
port = "sim://?speed=20"

[robots.down1]
port = "{dead}"
connect_timeout = 2

[robots.down2]
port = "{dead}"
connect_timeout = 2
"""


def _fleet_file(tmp_path: Path) -> str:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        dead = f"socket://127.0.0.1:{probe.getsockname()[1]}"
    path = tmp_path / "fleet.toml"
    path.write_text(FLEET.format(dead=dead))
    return str(path)


def _galileo(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "galileo_async", *args], capture_output=True,
                          text=True, timeout=60, check=False)  # fmt: skip


def test_fleet_status_exits_7_with_robots_down_and_takes_json_after_the_command(
    tmp_path: Path,
) -> None:
    done = _galileo("--fleet", _fleet_file(tmp_path), "fleet", "status", "--json")
    assert done.returncode == ExitCode.CONNECTION, done.stderr
    rows = [json.loads(line) for line in done.stdout.splitlines()]
    assert [(row["name"], row["state"]) for row in rows] == [
        ("alpha", "up"), ("down1", "lost"), ("down2", "lost"),
    ]  # fmt: skip
    assert all(row["time"].endswith("Z") for row in rows)
    assert rows[0]["status"]["power"] == round(rows[0]["status"]["power"], 2)
    assert rows[0]["status"]["nav_status"] in {0, 1}
    assert rows[1]["status"] is None


def test_fleet_status_exits_0_with_every_robot_up(tmp_path: Path) -> None:
    path = tmp_path / "up.toml"
    path.write_text('[robots.a]\nport = "sim://?speed=20"\n[robots.b]\nport = "sim://?speed=20"\n')
    done = _galileo("--fleet", str(path), "fleet", "status")
    assert done.returncode == ExitCode.OK, done.stderr
    assert "2 robots · up 2 · goals running 0" in done.stdout


async def test_fleet_status_at_80x24_keeps_a_row_per_robot(
    tmux: list[str],  # noqa: F811
    tmp_path: Path,
) -> None:
    fleet = _fleet_file(tmp_path)
    command = f"{sys.executable} -m galileo_async --fleet {fleet} fleet status; echo exited-$?"
    await keys(tmux, "clear; " + command, "Enter")
    screen = await until(tmux, lambda s: re.search(r"exited-[0-9]", s) is not None)
    assert "exited-7" in screen, screen
    lines = screen.splitlines()
    header = next(line for line in lines if "robot" in line and "link" in line)
    for column in ("goal", "nav", "distance"):
        assert column in header.split(), header
    for name, state in (("alpha", "up"), ("down1", "lost"), ("down2", "lost")):
        (row,) = [line for line in lines if f" {name} " in line]
        assert state in row.split(), row
    assert "goals running 0" in screen
