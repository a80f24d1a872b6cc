"""The options, described once (galileo_async.options): typed, derived, checked once."""

from __future__ import annotations

import collections
import json
import re
import subprocess
import sys
from pathlib import Path
from typing import Any
from unittest import mock

import anyio
import pytest

import galileo_async as galileo
from galileo_async import links
from galileo_async.fleet.file import FleetFileError, parse_fleet
from galileo_async.options import LINK_KINDS, OPTIONS, Option, names_for, option_table
from galileo_async.sim import Simulator
from tests.support.ros_support import RobotNode, RosMaster

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

ROOT = Path(__file__).resolve().parents[2]
#: A URL of each link kind; nothing is opened by connect() itself.
URLS = {
    "serial": "/dev/ttyUSB0",
    "socket": "socket://127.0.0.1:1",
    "udp": "udp://127.0.0.1:1",
    "sim": "sim://",
    "ros": "ros://127.0.0.1:1",
    "http": "https://127.0.0.1:1",
}
#: A value each option takes where its default is None (TOML has no None).
SAMPLES: dict[str, Any] = {
    "map_targets": 4,
    "serial_options": {"exclusive": False},
    "host": "127.0.0.1",
    "bind": "127.0.0.1",
    "node_name": "/fleet_test",
    "hosts": "xiaoqiang-desktop=10.0.0.5",
    "username": "admin",
    "password": "admin",
    "token": "a-token",
    "ca_file": __file__,
}


def sample(name: str, kind: str) -> Any:
    if name == "layout":
        return "ros" if kind in ("ros", "http") else "v1"
    default = OPTIONS[name].default
    return SAMPLES[name] if default is None else default


def toml_value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, dict):
        return "{ " + ", ".join(f"{k} = {toml_value(v)}" for k, v in value.items()) + " }"
    return json.dumps(value) if isinstance(value, str) else repr(value)


def test_every_link_kind_has_a_url_here() -> None:
    assert set(URLS) == set(LINK_KINDS)
    assert {links.link_kind(url) for url in URLS.values()} == set(LINK_KINDS)


def test_the_description_gives_every_option_a_type_default_and_doc() -> None:
    for name, option in OPTIONS.items():
        assert option.name == name
        assert option.type is not None, name
        assert option.doc, name
        assert option.kinds is None or option.kinds <= set(LINK_KINDS), name
    assert "hosts" in names_for("ros")
    assert "hosts" not in names_for("socket")
    assert "layout" not in names_for("udp")


@pytest.mark.parametrize("kind", LINK_KINDS)
def test_a_fleet_file_takes_every_option_connect_takes_for_that_kind(kind: str) -> None:
    names = sorted(names_for(kind))
    table = "\n".join(f"{name} = {toml_value(sample(name, kind))}" for name in names)
    text = f'[robots.r]\nport = "{URLS[kind]}"\n{table}\n'
    spec = parse_fleet(tomllib.loads(text), "fleet.toml")
    assert sorted(spec.robot_options["r"]) == names
    galileo.connect(URLS[kind], **spec.robot_options["r"])  # checks, opens nothing


def test_a_fleet_of_ros_robots_can_set_hosts_as_a_table() -> None:
    text = '[defaults.hosts]\nxiaoqiang-desktop = "10.0.0.5"\n[robots.r]\nport = "ros://h"\n'
    spec = parse_fleet(tomllib.loads(text), "fleet.toml")
    assert spec.defaults == {"hosts": {"xiaoqiang-desktop": "10.0.0.5"}}
    galileo.connect("ros://h", **spec.defaults)


def test_a_fleet_file_names_the_types_an_option_takes() -> None:
    data = {"robots": {"r": {"port": "ros://h", "hosts": 5}}}
    with pytest.raises(FleetFileError, match="hosts must be str or table, got 5"):
        parse_fleet(data, "fleet.toml")


async def connect_counting(url: str, options: dict[str, Any]) -> collections.Counter[str]:
    """How often each option's check ran while connecting (and opening) ``url``."""
    checked: collections.Counter[str] = collections.Counter()
    original = Option.check

    def counting(self: Option, value: object, kind: str | None = None) -> None:
        checked[self.name] += 1
        original(self, value, kind)

    with mock.patch.object(Option, "check", counting):
        async with galileo.connect(url, **options) as robot:
            assert robot.status is not None
    return checked


OPTIONS_GIVEN: dict[str, Any] = {
    "stale_timeout": 5.0, "reconnect_initial": 0.05, "accept_timeout": 4.0,
    "arrive_tolerance": 0.2, "max_linear_speed": 0.8, "first_status_timeout": 5.0,
    "min_command_interval": 0.01, "drain_timeout": 2.0, "max_queued_commands": 50,
    "connect_timeout": 2.0, "baudrate": 115200,
}  # fmt: skip


async def test_each_option_is_checked_once_per_connect_on_sim() -> None:
    with anyio.fail_after(10):
        checked = await connect_counting("sim://?speed=20", OPTIONS_GIVEN)
    assert checked == dict.fromkeys(OPTIONS_GIVEN, 1)


async def test_each_option_is_checked_once_per_connect_on_a_socket() -> None:
    async with Simulator(speed=20) as sim:
        server = await sim.serve_tcp()
        url = f"socket://127.0.0.1:{server.sockets[0].getsockname()[1]}"
        with anyio.fail_after(10):
            checked = await connect_counting(url, OPTIONS_GIVEN)
    assert checked == dict.fromkeys(OPTIONS_GIVEN, 1)


async def test_each_option_is_checked_once_per_connect_on_ros(tmp_path: Path) -> None:
    given: dict[str, Any] = {
        "host": "127.0.0.1", "node_name": "/checked_once", "rpc_timeout": 2.0,
        "master_check_interval": 1.0, "hosts": "xiaoqiang-desktop=127.0.0.1",
        "layout": "ros", "stale_timeout": 5.0, "accept_timeout": 4.0, "baudrate": 9600,
    }  # fmt: skip
    async with RosMaster.running(tmp_path) as master, RobotNode.running(master):
        with anyio.fail_after(20):
            checked = await connect_counting(f"{master.url}?connect_timeout=5", given)
    assert checked == dict.fromkeys([*given, "connect_timeout"], 1)


MISSPELT = """\
from __future__ import annotations

import galileo_async


async def main() -> None:
    async with galileo_async.connect("sim://", stale_timout=1.0) as robot:
        print(robot)
    await galileo_async.connect("ros://h", stale_timeout="soon")
    await galileo_async.connect("ros://h", stale_timeout=None, hosts={"a": "10.0.0.5"})
"""


def test_a_misspelt_option_is_a_type_error(tmp_path: Path) -> None:
    pytest.importorskip("mypy")
    snippet = tmp_path / "snippet.py"
    snippet.write_text(MISSPELT)
    result = subprocess.run(
        [sys.executable, "-m", "mypy", "--strict", "--cache-dir", str(tmp_path / "cache"),
         str(snippet)],
        capture_output=True, text=True, timeout=300, cwd=ROOT, check=False,
    )  # fmt: skip
    errors = [line for line in result.stdout.splitlines() if ": error:" in line]
    assert len(errors) == 2, result.stdout
    assert 'snippet.py:7: error: Unexpected keyword argument "stale_timout"' in errors[0]
    assert 'did you mean "stale_timeout"?' in errors[0]
    assert re.search(r'snippet.py:9: error: Argument "stale_timeout" .* "str"', errors[1])


DOCS_TABLE = re.compile(
    r"<!-- options table: generated from galileo_async.options.OPTIONS -->\n(.*?)"
    r"<!-- end of options table -->",
    re.DOTALL,
)


def test_the_docs_option_table_is_the_description() -> None:
    text = (ROOT / "docs" / "robot.md").read_text(encoding="utf-8")
    tables = DOCS_TABLE.findall(text)
    assert len(tables) == 1
    assert tables[0] == option_table(), (
        "docs/robot.md's option table differs from galileo_async.options.OPTIONS: paste "
        "option_table() between its markers"
    )
    for name in OPTIONS:
        assert f"| `{name}` |" in tables[0]
