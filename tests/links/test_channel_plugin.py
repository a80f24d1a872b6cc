"""A scheme from another distribution: docs/transports.md's example channel, installed as one.

The distribution is a module and a ``.dist-info`` with its entry point on PYTHONPATH (what
an installer leaves in site-packages), so the test runs offline; each use runs in a fresh
process, where the entry point is found the way an installed plugin's is.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
#: What each process may take: a simulated robot at speed 50 connects in well under this.
TIMEOUT = 120
MODULE = "galileo_demo_channel"


def example_module() -> str:
    """The definitions of docs/transports.md's "Writing a channel" example, up to register()."""
    page = (ROOT / "docs" / "transports.md").read_text(encoding="utf-8")
    section = page[page.index("## Writing a channel") :]
    start = section.index("```python\n") + len("```python\n")
    code = section[start : section.index("\n```", start)]
    head, found, _ = code.partition("\nregister(SCHEME)")
    assert found, "the example no longer registers SCHEME: update this test"
    return head + "\n"


@pytest.fixture(scope="module")
def plugin_path(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A directory holding the installed distribution (module + dist-info with entry point)."""
    site = tmp_path_factory.mktemp("site")
    (site / f"{MODULE}.py").write_text(example_module(), encoding="utf-8")
    info = site / f"{MODULE}-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text(
        "Metadata-Version: 2.1\nName: galileo-demo-channel\nVersion: 0.1\n", encoding="utf-8"
    )
    (info / "entry_points.txt").write_text(
        f"[galileo_async.channels]\ndemo = {MODULE}:SCHEME\n", encoding="utf-8"
    )
    return site


def run(plugin_path: Path, *args: str, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(plugin_path), str(ROOT)])}
    env.pop("GALILEO_PORT", None)
    env.pop("GALILEO_FLEET", None)
    env.pop("GALILEO_ROBOT", None)
    return subprocess.run(
        [sys.executable, *args],
        capture_output=True,
        text=True,
        env=env,
        cwd=cwd,
        timeout=TIMEOUT,
        check=False,
    )


CONNECT = """
import asyncio, galileo_async
from galileo_async.errors import InvalidArgument
from galileo_async.links import link_kind, url_forms

async def main():
    assert link_kind("demo://x") == "demo"
    assert "demo://NAME" in url_forms()
    async with galileo_async.connect("demo://one", demo_speed=50.0) as robot:
        await robot.start_navigation()
        result = await robot.goto(1)
        print("reached", result.target_id, type(robot._link.channel).__name__)
    for bad, said in (({"demo_speed": -1.0}, "positive"), ({"demo_sped": 1.0}, "demo_speed")):
        try:
            await galileo_async.connect("demo://two", **bad)
        except InvalidArgument as exc:
            assert said in str(exc), exc
        else:
            raise AssertionError(bad)
    try:  # the scheme's own option is for its URLs only
        await galileo_async.connect("sim://", demo_speed=50.0)
    except InvalidArgument as exc:
        print("sim refuses:", exc)

asyncio.run(main())
"""


def test_connect_takes_the_plugins_scheme_and_options(plugin_path: Path) -> None:
    done = run(plugin_path, "-c", CONNECT)
    assert done.returncode == 0, done.stderr
    assert "reached 1 DemoChannel" in done.stdout
    assert "sim refuses: connect('sim://'): unknown option 'demo_speed'" in done.stdout


def test_the_cli_prints_a_status_of_the_plugins_robot(plugin_path: Path) -> None:
    done = run(plugin_path, "-m", "galileo_async", "-p", "demo://one", "status", "--json")
    assert done.returncode == 0, done.stderr
    line = json.loads(done.stdout.splitlines()[-1])
    assert line["port"] == "demo://one"
    assert line["status"]["layout"] == "v2"
    assert line["link"]["state"] == "up"


def test_a_fleet_file_takes_the_plugins_scheme_and_options(
    plugin_path: Path, tmp_path: Path
) -> None:
    fleet = tmp_path / "fleet.toml"
    fleet.write_text(
        '[defaults]\ndemo_speed = 40\n\n[robots.alpha]\nport = "demo://alpha"\n'
        'demo_speed = 50.0\n\n[robots.beta]\nport = "demo://beta"\n',
        encoding="utf-8",
    )
    done = run(
        plugin_path, "-m", "galileo_async", "--fleet", str(fleet), "fleet", "status", "--json"
    )
    assert done.returncode == 0, done.stderr
    lines = [json.loads(line) for line in done.stdout.splitlines()]
    assert {line["name"] for line in lines} == {"alpha", "beta"}
    assert all(line["state"] == "up" and line["status"] is not None for line in lines), lines
    # One robot of the file by name: its port and options (demo_speed) from the file.
    done = run(
        plugin_path, "-m", "galileo_async", "--fleet", str(fleet), "-r", "alpha", "status",
        "--json",
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout.splitlines()[-1])["port"] == "demo://alpha"
    fleet.write_text('[robots.alpha]\nport = "demo://alpha"\ndemo_speed = "fast"\n')
    done = run(
        plugin_path, "-m", "galileo_async", "--fleet", str(fleet), "fleet", "status", "--json"
    )
    assert done.returncode != 0
    assert "demo_speed must be float" in done.stdout + done.stderr
