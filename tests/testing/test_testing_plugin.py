"""The pytest plugin (galileo_async_pytest): fixtures, galileo_sim, leak checks, what it loads."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import pytest

from galileo_async import Robot
from galileo_async.protocol import commands as c
from galileo_async.testing import SimulatedDevice, VirtualClock

pytest_plugins = ["pytester"]

#: The worktree whose galileo_async the pytest runs below import.
ROOT = Path(__file__).resolve().parents[2]
#: Real seconds one pytest run below may take.
RUN_TIMEOUT = 60.0


@pytest.fixture
def run(pytester: pytest.Pytester, monkeypatch: pytest.MonkeyPatch) -> pytest.Pytester:
    """A pytester whose runs import this worktree's galileo_async."""
    path = os.environ.get("PYTHONPATH")
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join(filter(None, [str(ROOT), path])))
    monkeypatch.delenv("PYTEST_ADDOPTS", raising=False)
    return pytester


def pytest_run(pytester: pytest.Pytester, *args: str) -> pytest.RunResult:
    """Run pytest in a subprocess on the files written, small and bounded."""
    return pytester.runpytest_subprocess(
        "-p", "no:cacheprovider", "-q", "-rA", *args, timeout=RUN_TIMEOUT
    )


# ----------------------------------------------------------------------- in this suite


@pytest.mark.galileo_sim(map_targets=4, accept_timeout=2.0)
async def test_the_fixtures_are_two_halves_of_one_robot(
    galileo_robot: Robot, galileo_device: SimulatedDevice
) -> None:
    assert VirtualClock.of() is not None
    assert galileo_robot.map_targets == 4
    assert galileo_robot.accept_timeout == 2.0
    assert len(galileo_device.state.targets) == 4
    assert (await galileo_robot.goto(3)).target_id == 3
    assert galileo_device.received() == [c.Goto(3)]


# ----------------------------------------------------------------------- in a pytest run

STRICT_MODE_TESTS = """
import asyncio

import pytest

from galileo_async.protocol import commands as c

pytestmark = pytest.mark.asyncio


async def test_fixtures(galileo_robot, galileo_device):
    assert galileo_device.commands == []  # a fresh robot per test
    assert (await galileo_robot.goto(0)).target_id == 0
    assert galileo_device.received() == [c.Goto(0)]
    await asyncio.sleep(3600)  # virtual: returns at once


async def test_fixtures_again(galileo_robot, galileo_device):
    assert galileo_device.commands == []
    assert galileo_robot.status.target_num_id == -1  # not the last test's goal 0


@pytest.mark.galileo_sim(
    firmware="document", map_targets=3, layout="v1", accept_timeout=2.0,
    sim_options={"power": 21.0},
)
async def test_marker(galileo_robot, galileo_device):
    assert galileo_device.simulator.config.firmware == "document"
    assert galileo_robot.map_targets == 3
    assert len(galileo_device.state.targets) == 3
    assert galileo_robot.accept_timeout == 2.0
    assert galileo_robot.status.layout == "v1"
    assert galileo_device.status.power == pytest.approx(21.0, abs=0.1)


@pytest.mark.galileo_sim(navigating=False)
class TestClassMarker:
    async def test_navigation_closed(self, galileo_robot):
        assert galileo_robot.status.nav_status == 0


async def test_no_leaks_on_a_plain_test(galileo_no_leaks):
    task = asyncio.create_task(asyncio.sleep(1))
    await task
"""


def test_fixtures_and_marker_in_strict_mode_with_strict_markers(run: pytest.Pytester) -> None:
    run.makeini("[pytest]\nasyncio_mode = strict\nasyncio_default_fixture_loop_scope = function\n")
    run.makepyfile(
        test_sim=STRICT_MODE_TESTS,
        # The control: --strict-markers is on, and refuses a marker nobody declared.
        test_typo="import pytest\n\n@pytest.mark.galileo_simm\ndef test_x():\n    pass\n",
    )
    result = pytest_run(run, "--strict-markers", "--continue-on-collection-errors")
    result.assert_outcomes(passed=5, errors=1)
    result.stdout.fnmatch_lines(["ERROR test_typo.py*'galileo_simm' not found in `markers`*"])
    assert "'galileo_sim' not found" not in result.stdout.str()


LEAKING_TESTS = """
import asyncio

import pytest

import galileo_async

pytestmark = pytest.mark.asyncio
KEPT = []


async def test_leaves_a_robot(galileo_device):
    KEPT.append(await galileo_async.connect(galileo_device.simulator.url))


async def test_drops_an_open_robot(galileo_device):
    await galileo_async.connect(galileo_device.simulator.url)  # no reference kept: still named


async def test_leaves_a_task(galileo_robot):
    asyncio.create_task(asyncio.Event().wait(), name="forgotten-task")


async def test_leaves_a_timer(galileo_robot):
    asyncio.get_running_loop().call_later(100, print, "forgotten-timer")


async def test_plain_test_leaves_a_task(galileo_no_leaks):
    asyncio.create_task(asyncio.Event().wait(), name="plain-task")
"""


def test_a_test_that_leaves_something_fails_at_teardown_naming_it(run: pytest.Pytester) -> None:
    run.makeini("[pytest]\nasyncio_default_fixture_loop_scope = function\n")
    run.makepyfile(test_leaks=LEAKING_TESTS)
    result = pytest_run(run)
    result.assert_outcomes(passed=5, errors=5)
    result.stdout.fnmatch_lines_random(
        [
            "*ERROR at teardown of test_leaves_a_robot*",
            "*1 Robot(s) left open: <Robot on <Link sim://simulator-*",
            "*ERROR at teardown of test_drops_an_open_robot*",
            "*1 Robot(s) left open: <Robot on <Link sim://simulator-*",
            "*ERROR at teardown of test_leaves_a_task*",
            "*1 task(s) left running: forgotten-task*",
            "*ERROR at teardown of test_leaves_a_timer*",
            "*1 timer(s) left armed*forgotten-timer*",
            "*ERROR at teardown of test_plain_test_leaves_a_task*",
            "*1 task(s) left running: plain-task*",
        ]
    )


AUTO_MODE_TESTS = """
import pytest


async def test_auto_mode(galileo_robot, galileo_device):
    assert (await galileo_robot.goto(1)).target_id == 1
    await galileo_device.advance(10)


@pytest.mark.galileo_sim("document")
async def test_positional(galileo_robot):
    pass
"""


def test_auto_mode_and_a_marker_with_positional_arguments(run: pytest.Pytester) -> None:
    run.makeini("[pytest]\nasyncio_mode = auto\nasyncio_default_fixture_loop_scope = function\n")
    run.makepyfile(test_auto=AUTO_MODE_TESTS)
    result = pytest_run(run)
    result.assert_outcomes(passed=1, errors=1)
    result.stdout.fnmatch_lines(
        [
            "*ERROR at setup of test_positional*",
            "*galileo_sim takes keyword arguments only, got ('document',)*",
        ]
    )


FLEET_TESTS = """
import asyncio

import pytest

from galileo_async import LinkState
from galileo_async.protocol import commands as c

pytestmark = pytest.mark.asyncio


async def test_default_fleet(galileo_fleet, galileo_devices):
    assert list(galileo_fleet) == ["robot1", "robot2", "robot3"]
    await galileo_fleet.get("robot2").goto(1)
    assert galileo_devices["robot2"].received(c.Goto) == [c.Goto(1)]
    assert galileo_devices["robot1"].commands == []


@pytest.mark.galileo_fleet_sim(robots=["a", "b"], sim_options={"power": 21.0})
async def test_marked_fleet(galileo_fleet, galileo_devices):
    assert list(galileo_fleet) == ["a", "b"]
    assert galileo_fleet.get("a").status.power == 21.0
    galileo_devices["b"].drop_link()
    await galileo_devices["b"].advance(1)
    assert galileo_fleet.state("b") is LinkState.LOST
    assert galileo_fleet.state("a") is LinkState.UP


async def test_fleet_leaves_a_goto(galileo_fleet):
    asyncio.create_task(galileo_fleet.get("robot1").goto(2), name="forgotten-goto")
    await asyncio.sleep(0.5)
"""


def test_fleet_fixtures_and_their_marker(run: pytest.Pytester) -> None:
    run.makeini("[pytest]\nasyncio_default_fixture_loop_scope = function\n")
    run.makepyfile(test_fleet=FLEET_TESTS)
    result = pytest_run(run, "--strict-markers")
    result.assert_outcomes(passed=3, errors=1)
    result.stdout.fnmatch_lines(
        [
            "*ERROR at teardown of test_fleet_leaves_a_goto*",
            "*1 task(s) left running: forgotten-goto*",
        ]
    )


UNMARKED_TESTS = """
import asyncio

import pytest


async def test_unmarked_with_the_fixtures(galileo_robot, galileo_device):
    pass


async def test_unmarked_plain():
    await asyncio.sleep(0)


@pytest.mark.asyncio
async def test_marked(galileo_robot):
    assert galileo_robot.status is not None


@pytest.fixture
def anyio_backend():
    return "asyncio"


@pytest.mark.anyio
async def test_run_by_anyio():
    await asyncio.sleep(0)


@pytest.mark.asyncio
async def test_a_failure_of_its_own_is_kept():
    pytest.fail("async def functions are not natively supported: the test's own words")
"""


def test_an_unmarked_test_in_strict_mode_says_what_to_add(run: pytest.Pytester) -> None:
    run.makeini("[pytest]\nasyncio_mode = strict\nasyncio_default_fixture_loop_scope = function\n")
    run.makepyfile(test_unmarked=UNMARKED_TESTS)
    result = pytest_run(run, "-p", "anyio")
    result.assert_outcomes(passed=2, failed=3)
    result.stdout.fnmatch_lines(
        [
            "*_ test_unmarked_with_the_fixtures _*",
            "async test not run: pytest-asyncio's strict mode runs only the async tests marked "
            "asyncio; galileo_device, galileo_robot need it. Add @pytest.mark.asyncio to the test"
            " (or pytestmark = pytest.mark.asyncio to its module), or set asyncio_mode = "
            '"auto" under [[]tool.pytest.ini_options[]] in pyproject.toml (asyncio_mode = auto in'
            " pytest.ini) to run every async test on asyncio.",
            "*_ test_unmarked_plain _*",
            "async test not run: pytest-asyncio's strict mode runs only the async tests marked "
            "asyncio. Add @pytest.mark.asyncio to the test*",
            "*_ test_a_failure_of_its_own_is_kept _*",
            "*Failed: async def functions are not natively supported: the test's own words",
        ]
    )
    result.stdout.fnmatch_lines_random(
        ["PASSED test_unmarked.py::test_marked", "PASSED test_unmarked.py::test_run_by_anyio"]
    )
    assert "not natively supported.\n" not in result.stdout.str()  # pytest's generic words


def test_without_pytest_asyncio_or_the_fixtures_pytest_keeps_its_words(
    run: pytest.Pytester,
) -> None:
    run.makepyfile(test_plain="async def test_unrun():\n    pass\n")
    result = pytest_run(run, "-p", "no:asyncio")
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(["*async def functions are not natively supported*"])
    assert "async test not run" not in result.stdout.str()


# ----------------------------------------------------------------------- what it loads

#: Prints, as the session ends, the modules of galileo-async the session imported.
LOADED_MODULES_CONFTEST = """
import json
import sys


def pytest_sessionfinish(session):
    loaded = sorted(name for name in sys.modules if name.startswith("galileo_async"))
    config = session.config
    report = {
        "modules": loaded,
        "plugin": config.pluginmanager.has_plugin("galileo_async"),
        "marker": any(line.startswith("galileo_sim(") for line in config.getini("markers")),
    }
    print("\\nLOADED " + json.dumps(report))
"""


def loaded_report(result: pytest.RunResult) -> dict[str, Any]:
    """What the conftest above printed at the end of the session."""
    (line,) = (line for line in result.stdout.lines if line.startswith("LOADED "))
    report: dict[str, Any] = json.loads(line.removeprefix("LOADED "))
    return report


def test_an_unrelated_session_loads_no_module_of_the_package(
    run: pytest.Pytester, monkeypatch: pytest.MonkeyPatch
) -> None:
    # Any project's session, with galileo-async installed: the plugin comes through the
    # installed entry point, and must not load the package while nothing of it is used.
    monkeypatch.delenv("PYTEST_DISABLE_PLUGIN_AUTOLOAD", raising=False)
    run.makeconftest(LOADED_MODULES_CONFTEST)
    run.makepyfile(test_unrelated="def test_arithmetic():\n    assert 1 + 1 == 2\n")
    result = pytest_run(run, "-s")
    result.assert_outcomes(passed=1)
    report = loaded_report(result)
    assert report["plugin"]  # loaded through its entry point
    assert report["marker"]  # and its marker declared
    assert len(report["modules"]) <= 2, report["modules"]
    assert report["modules"] == ["galileo_async_pytest"]  # the plugin alone, no package


def test_a_session_that_uses_the_fixtures_loads_them_when_used(
    run: pytest.Pytester, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.delenv("PYTEST_DISABLE_PLUGIN_AUTOLOAD", raising=False)
    run.makeconftest(LOADED_MODULES_CONFTEST)
    run.makeini("[pytest]\nasyncio_mode = auto\nasyncio_default_fixture_loop_scope = function\n")
    run.makepyfile(
        test_app="""
import pytest


@pytest.mark.galileo_sim(map_targets=2)
async def test_goes(galileo_robot, galileo_device):
    assert (await galileo_robot.goto(1)).target_id == 1
    assert [type(c).__name__ for c in galileo_device.received()] == ["Goto"]
"""
    )
    result = pytest_run(run, "-s")
    result.assert_outcomes(passed=1)
    modules = loaded_report(result)["modules"]
    # The report sees what a session loads: here the simulated robot behind the fixture.
    assert {"galileo_async_pytest", "galileo_async.testing.robot"} <= set(modules)
