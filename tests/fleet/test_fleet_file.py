"""Fleet files: TOML parsed into ports and options; every mistake named by robot and key."""

from __future__ import annotations

from pathlib import Path

import anyio
import pytest

from galileo_async import LinkState
from galileo_async.errors import InvalidArgument
from galileo_async.fleet.file import FleetFileError, load_fleet_file

GOOD = """
targets = "targets.csv"

[defaults]
stale_timeout = 2
first_status_timeout = 5.0

[robots.alpha]
port = "sim://?speed=20"
map_targets = 4

[robots.beta]
port = "sim://?layout=v1"
layout = "v1"
reconnect = false
"""


def write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "fleet.toml"
    path.write_text(text)
    return path


def test_a_good_file(tmp_path: Path) -> None:
    spec = load_fleet_file(write(tmp_path, GOOD))
    assert spec.ports == {"alpha": "sim://?speed=20", "beta": "sim://?layout=v1"}
    assert spec.robot_options == {
        "alpha": {"map_targets": 4},
        "beta": {"layout": "v1", "reconnect": False},
    }
    assert spec.defaults == {"stale_timeout": 2.0, "first_status_timeout": 5.0}
    assert isinstance(spec.defaults["stale_timeout"], float)
    assert spec.targets == tmp_path / "targets.csv"


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("", "no robots"),
        ("[robots]\n", "no robots"),
        ("robots = 3\n", "no robots"),
        ('colour = "red"\n[robots.a]\nport = "sim://"\n', "unknown key 'colour'"),
        ("[robots.a]\nmap_targets = 3\n", "robot 'a': port must be a non-empty string"),
        ('[robots.a]\nport = ""\n', "robot 'a': port must be"),
        ('[robots.a]\nport = "sim://"\nspeed = 3\n', "robot 'a': unknown option 'speed'"),
        (
            '[robots.a]\nport = "sim://"\nwait_timout = 3\n',
            "robot 'a': unknown option 'wait_timout'; did you mean 'wait_timeout'[?]$",
        ),
        ('[defaults]\nlayot = "v1"\n[robots.a]\nport = "sim://"\n', "did you mean 'layout'"),
        (
            '[robots.a]\nport = "sim://"\nmap_targets = "six"\n',
            "robot 'a': map_targets must be int",
        ),
        ('[robots.a]\nport = "sim://"\nmap_targets = true\n', "robot 'a': map_targets must be int"),
        ('[robots.a]\nport = "sim://"\nreconnect = 1\n', "robot 'a': reconnect must be bool"),
        ('[defaults]\nlayout = 2\n[robots.a]\nport = "sim://"\n', r"\[defaults\]: layout must be"),
        ('targets = 5\n[robots.a]\nport = "sim://"\n', "targets must be a path"),
        ("[robots.a\n", "not valid TOML"),
    ],
)
def test_mistakes_are_named(tmp_path: Path, text: str, message: str) -> None:
    path = write(tmp_path, text)
    with pytest.raises(FleetFileError, match=message) as info:
        load_fleet_file(path)
    assert str(path) in str(info.value)
    assert isinstance(info.value, InvalidArgument)


def test_a_missing_file(tmp_path: Path) -> None:
    with pytest.raises(FleetFileError, match="cannot read the fleet file"):
        load_fleet_file(tmp_path / "nope.toml")


async def test_connecting_the_file(tmp_path: Path) -> None:
    spec = load_fleet_file(write(tmp_path, GOOD))
    with anyio.fail_after(10):
        async with spec.connect() as fleet:
            assert fleet.states() == {"alpha": LinkState.UP, "beta": LinkState.UP}
            assert fleet["alpha"].map_targets == 4
            assert fleet["beta"].link.layout is not None


async def test_a_value_connect_rejects_names_the_robot(tmp_path: Path) -> None:
    spec = load_fleet_file(write(tmp_path, '[robots.a]\nport = "sim://"\nmap_targets = 999\n'))
    with anyio.fail_after(10), pytest.raises(InvalidArgument, match=r"robot 'a': .*map_targets"):
        async with spec.connect():
            pass  # pragma: no cover


def test_vehicle_identities_are_not_connect_options(tmp_path: Path) -> None:
    text = GOOD.replace(
        "map_targets = 4", 'map_targets = 4\nserial_number = "A-1"\nmanufacturer = "zeta"'
    )
    spec = load_fleet_file(write(tmp_path, text))
    assert spec.robot_options["alpha"] == {"map_targets": 4}
    assert spec.serial_number("alpha") == "A-1"
    assert spec.manufacturer("alpha", "acme") == "zeta"
    assert spec.serial_number("beta") == "beta"  # its name by default
    assert spec.manufacturer("beta", "acme") == "acme"
    only = spec.only(["beta"])
    assert list(only.ports) == ["beta"]
    assert only.vehicle_ids == {}
    assert only.defaults == spec.defaults


@pytest.mark.parametrize("value", ['""', "7"])
def test_a_bad_serial_number_is_named(tmp_path: Path, value: str) -> None:
    text = GOOD.replace("map_targets = 4", f"serial_number = {value}")
    with pytest.raises(FleetFileError, match="robot 'alpha': serial_number must be a non-empty"):
        load_fleet_file(write(tmp_path, text))
