"""Named robots (-r NAME, GALILEO_ROBOT) from the config file or a fleet file; completion."""

from __future__ import annotations

import json
import os
import subprocess
from pathlib import Path

import pytest

from galileo_async.cli import ExitCode
from tests.cli.test_cli_served import GALILEO, WAIT

CONFIG = """
[defaults]
wait_timeout = 20.0

[robots.lab]
port = "sim://?speed=20&layout=v1"

[robots.broken]
port = "sim://"
stale_timeout = -1.0
"""


@pytest.fixture
def config_home(tmp_path: Path) -> Path:
    """A temporary XDG_CONFIG_HOME holding galileo/config.toml."""
    (tmp_path / "galileo").mkdir()
    (tmp_path / "galileo" / "config.toml").write_text(CONFIG, encoding="utf-8")
    return tmp_path


def galileo(*args: str, config_home: Path, **env: str) -> subprocess.CompletedProcess[str]:
    """``galileo args…`` with XDG_CONFIG_HOME=config_home, no GALILEO_PORT/ROBOT unless given."""
    base = {k: v for k, v in os.environ.items() if k not in ("GALILEO_PORT", "GALILEO_ROBOT")}
    full = {**base, "XDG_CONFIG_HOME": str(config_home), "COLUMNS": "200", **env}
    return subprocess.run(
        [*GALILEO, *args], capture_output=True, text=True, timeout=WAIT, env=full, check=False
    )


def layout_of(result: subprocess.CompletedProcess[str]) -> object:
    assert result.returncode == 0, result.stderr
    return json.loads(result.stdout)["status"]["layout"]


def test_robot_by_name_from_the_config_file(config_home: Path) -> None:
    result = galileo("-r", "lab", "--json", "status", config_home=config_home)
    assert layout_of(result) == "v1"
    assert "built-in simulator" not in result.stderr  # the profile named the port


def test_robot_from_the_environment(config_home: Path) -> None:
    result = galileo("--json", "status", config_home=config_home, GALILEO_ROBOT="lab")
    assert layout_of(result) == "v1"


def test_port_option_beats_the_robot_variable(config_home: Path) -> None:
    result = galileo(
        "--port", "sim://?speed=20", "--json", "status", config_home=config_home,
        GALILEO_ROBOT="lab",
    )  # fmt: skip
    assert layout_of(result) == "v2"


def test_robot_option_beats_the_port_variable(config_home: Path) -> None:
    result = galileo(
        "-r", "lab", "--json", "status", config_home=config_home, GALILEO_PORT="sim://"
    )
    assert layout_of(result) == "v1"


def test_port_and_robot_options_together_are_a_usage_error(config_home: Path) -> None:
    result = galileo("-r", "lab", "--port", "sim://", "status", config_home=config_home)
    assert result.returncode == ExitCode.USAGE
    assert "give one" in result.stderr


def test_an_unknown_name_lists_the_known_ones(config_home: Path) -> None:
    result = galileo("-r", "nope", "status", config_home=config_home)
    assert result.returncode == ExitCode.USAGE
    assert "no robot named 'nope'" in result.stderr
    assert "lab, broken" in result.stderr
    assert "Traceback" not in result.stderr


def test_profile_options_are_checked_like_connect_options(config_home: Path) -> None:
    result = galileo("-r", "broken", "status", config_home=config_home)
    assert result.returncode == ExitCode.USAGE
    assert "robot 'broken'" in result.stderr
    assert "stale_timeout must be > 0" in result.stderr


#: Robots with a mistake each, beside the CONFIG's robots.
MISTAKES = """
[robots.typo]
port = "sim://"
wait_timout = 3.0

[robots.wrong_type]
port = "sim://"
stale_timeout = "soon"
"""


@pytest.fixture
def config_with_mistakes(config_home: Path) -> Path:
    """config_home whose config.toml also has robots with a mistake in their tables."""
    path = config_home / "galileo" / "config.toml"
    path.write_text(CONFIG + MISTAKES, encoding="utf-8")
    return config_home


def test_a_mistake_in_another_robot_does_not_stop_this_one(config_with_mistakes: Path) -> None:
    result = galileo("-r", "lab", "--json", "status", config_home=config_with_mistakes)
    assert layout_of(result) == "v1"


def test_an_unknown_option_of_the_robot_used_says_did_you_mean(
    config_with_mistakes: Path,
) -> None:
    result = galileo("-r", "typo", "status", config_home=config_with_mistakes)
    assert result.returncode == ExitCode.USAGE
    (line,) = result.stderr.splitlines()
    assert "robot 'typo'" in line
    assert "unknown option 'wait_timout'; did you mean 'wait_timeout'?" in line
    assert "stale_timeout" not in line  # no list of every option name
    assert "Traceback" not in result.stderr


def test_a_wrong_type_is_reported_when_its_robot_is_used(config_with_mistakes: Path) -> None:
    result = galileo("-r", "wrong_type", "status", config_home=config_with_mistakes)
    assert result.returncode == ExitCode.USAGE
    assert "robot 'wrong_type': stale_timeout must be float" in result.stderr


def test_completion_names_every_robot_despite_mistakes(config_with_mistakes: Path) -> None:
    result = galileo(
        config_home=config_with_mistakes, _GALILEO_COMPLETE="complete_bash",
        COMP_WORDS="galileo -r ", COMP_CWORD="2",
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    assert result.stdout.split() == ["lab", "broken", "typo", "wrong_type"]


def test_a_fleet_files_robot_by_name(config_home: Path, tmp_path: Path) -> None:
    fleet = tmp_path / "fleet.toml"
    fleet.write_text('[robots.beta]\nport = "sim://?speed=20&layout=v1_charge"\n')
    result = galileo(
        "--fleet", str(fleet), "-r", "beta", "--json", "status", config_home=config_home
    )
    assert layout_of(result) == "v1_charge"


def test_show_completion_prints_a_script() -> None:
    # Typer detects the shell from the parent process (sh under CI, where it refuses);
    # its test switch makes the shell an argument instead.
    result = galileo(
        "--show-completion", "bash", config_home=Path("/nonexistent"),
        _TYPER_COMPLETE_TEST_DISABLE_SHELL_DETECTION="1",
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    assert "_GALILEO_COMPLETE" in result.stdout


def test_completion_offers_commands_and_robot_names(config_home: Path) -> None:
    def complete(words: str) -> list[str]:
        result = galileo(
            config_home=config_home, _GALILEO_COMPLETE="complete_bash", COMP_WORDS=words,
            COMP_CWORD=str(len(words.split()) - 1),
        )  # fmt: skip
        assert result.returncode == 0, result.stderr
        return result.stdout.split()

    assert "nav" in complete("galileo na")
    assert complete("galileo -r l") == ["lab"]
