"""docs/missions.md stays true: its mission files load, and its console examples are what
`galileo mission` prints (its Python snippets run in tests/packaging/test_docs.py)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from galileo_async.missions import check_static, parse_mission
from galileo_async.missions.importers import import_nav2
from tests.cli.test_cli import invoke

PAGE = Path(__file__).parents[2] / "docs" / "missions.md"
TEXT = PAGE.read_text(encoding="utf-8")
YAML_BLOCKS = re.findall(r"```yaml\n(.*?)^```", TEXT, flags=re.S | re.M)
CONSOLE_BLOCKS = re.findall(r"```console\n(.*?)^```", TEXT, flags=re.S | re.M)


def console(command: str) -> str:
    """The console block that starts with ``$ command``."""
    for block in CONSOLE_BLOCKS:
        if block.startswith(f"$ {command}\n"):
            return str(block)
    raise AssertionError(f"no console block for {command!r}")


@pytest.mark.parametrize("block", YAML_BLOCKS)
def test_every_mission_file_of_the_page_loads(block: str) -> None:
    parse_mission(block, source="docs/missions.md")


def test_the_worked_example_checks_clean(tmp_path: Path) -> None:
    patrol = tmp_path / "patrol.yaml"
    patrol.write_text(YAML_BLOCKS[0], encoding="utf-8")
    assert [p.severity for p in check_static(parse_mission(YAML_BLOCKS[0]))] == ["note", "note"]
    block = console("galileo mission check patrol.yaml")
    expected = block.split("$ ")[1].splitlines()[1:]
    result = invoke("mission", "check", str(patrol), port=None)
    assert result.exit_code == 0
    assert result.stdout.replace(str(patrol), "patrol.yaml").splitlines() == expected
    against = invoke("mission", "check", str(patrol), port="sim://")
    assert against.exit_code == 2
    second = block.split("$ ")[2].splitlines()[1:-1]
    assert against.stdout.replace(str(patrol), "patrol.yaml").splitlines() == second


def test_the_nav2_example_is_what_import_prints(tmp_path: Path) -> None:
    block = console("galileo mission import --no-headings --loops 1 waypoints.yaml")
    source = tmp_path / "waypoints.yaml"
    source.write_text(
        "waypoints:\n  waypoint0: {pose: [1.5, 0.5, 0], orientation: [1, 0, 0, 0]}\n"
        "  waypoint1: {pose: [3.0, 0.5, 0], orientation: [1, 0, 0, 0]}\n",
        encoding="utf-8",
    )
    result = invoke("mission", "import", "--no-headings", "--loops", "1", str(source), port=None)
    assert result.exit_code == 0
    assert result.stdout == block.split("\n", 1)[1]
    assert parse_mission(result.stdout) == import_nav2(
        source.read_text(encoding="utf-8"), source=str(source), headings=False, loops=1
    )
