"""galileo_async's pytest plugin (entry point pytest11): galileo_robot, galileo_device, …

``galileo_robot`` and ``galileo_device`` are the two halves of one fresh
simulated_robot() per test, on a virtual clock; ``@pytest.mark.galileo_sim(...)`` passes
simulated_robot's arguments. ``galileo_fleet`` and ``galileo_devices`` are those of one
simulated_fleet() (``@pytest.mark.galileo_fleet_sim(...)``). A test that uses them fails
when it leaves a Robot, task or timer behind; ``galileo_no_leaks`` gives any async test
the same check. The fixtures need pytest-asyncio (the extra ``testing``); the plugin
loads without it. An async test no plugin ran (unmarked in pytest-asyncio's strict mode)
fails saying what to add, where pytest would say only that async tests need a plugin.

A module of its own beside the package: pytest loads it into every session of every
project that has galileo-async installed, and it imports nothing of galileo_async until
a test uses one of its fixtures.
"""

from __future__ import annotations

import contextlib
import inspect
from collections.abc import AsyncIterator, Callable, Collection, Generator
from typing import TYPE_CHECKING, Any, TypeVar

import pytest

if TYPE_CHECKING:
    from galileo_async.fleet import Fleet
    from galileo_async.robot import Robot
    from galileo_async.testing.device import SimulatedDevice

__all__ = [
    "galileo_device", "galileo_devices", "galileo_fleet", "galileo_fleet_simulation",
    "galileo_no_leaks", "galileo_robot", "galileo_simulation",
]  # fmt: skip

MARKER = "galileo_sim"
FLEET_MARKER = "galileo_fleet_sim"
_MARKER_HELP = (
    f"{MARKER}(firmware='real', layout='v2', map_targets=None, targets=None, "
    "navigating=True, clock='virtual', sim_options=None, **connect_options): "
    "the simulated robot behind the galileo_robot and galileo_device fixtures"
)
_FLEET_MARKER_HELP = (
    f"{FLEET_MARKER}(robots=3, firmware='real', targets=None, navigating=True, "
    "clock='virtual', sim_options=None, robot_sim_options=None, **options): "
    "the simulated fleet behind the galileo_fleet and galileo_devices fixtures"
)
_Pair = TypeVar("_Pair")
#: The fixtures this plugin gives (an async test using one is run by pytest-asyncio only).
FIXTURES = frozenset({
    "galileo_device", "galileo_devices", "galileo_fleet", "galileo_fleet_simulation",
    "galileo_no_leaks", "galileo_robot", "galileo_simulation",
})  # fmt: skip


def pytest_configure(config: pytest.Config) -> None:
    """Declare the markers (so --strict-markers accepts them)."""
    config.addinivalue_line("markers", _MARKER_HELP)
    config.addinivalue_line("markers", _FLEET_MARKER_HELP)


def _asyncio_mode(config: pytest.Config) -> str | None:
    """pytest-asyncio's mode ("strict", "auto"), or None when its plugin is not active."""
    if not config.pluginmanager.has_plugin("asyncio"):
        return None
    try:
        mode = config.getoption("asyncio_mode", None) or config.getini("asyncio_mode")
    except ValueError:  # another plugin named "asyncio"
        return None
    return str(mode)


def unrun_async_test_message(item: pytest.Function) -> str | None:
    """What to add to run ``item``, an async test no plugin ran; None if it is not ours to say.

    Ours to say: the test uses this plugin's fixtures, or pytest-asyncio runs in strict mode.
    """
    function = item.obj
    if not (inspect.iscoroutinefunction(function) or inspect.isasyncgenfunction(function)):
        return None
    mode = _asyncio_mode(item.config)
    ours = sorted(FIXTURES.intersection(item.fixturenames))
    if mode != "strict" and not ours:
        return None
    try:
        parameters: Collection[str] = inspect.signature(function).parameters
    except (TypeError, ValueError):
        parameters = ()
    asked = [name for name in ours if name in parameters]
    shown = asked or ours
    why = f"; {', '.join(shown)} {'needs' if len(shown) == 1 else 'need'} it" if shown else ""
    if mode == "strict":
        plugin = "pytest-asyncio's strict mode runs only the async tests marked asyncio"
    elif mode is None:
        plugin = "pytest-asyncio is not active (pip install 'galileo-async[testing]')"
    else:
        plugin = f"pytest-asyncio ({mode} mode) did not run it"
    return (
        f"async test not run: {plugin}{why}. Add @pytest.mark.asyncio to the test (or "
        'pytestmark = pytest.mark.asyncio to its module), or set asyncio_mode = "auto" under '
        "[tool.pytest.ini_options] in pyproject.toml (asyncio_mode = auto in pytest.ini) to run "
        "every async test on asyncio."
    )


#: What pytest says of an async test no plugin ran (a failure from pytest 8.4, a skip before).
_PYTESTS_WORDS = "async def functions are not natively supported"


@pytest.hookimpl(wrapper=True)
def pytest_pyfunc_call(pyfuncitem: pytest.Function) -> Generator[None, object, object]:
    """Where pytest fails (or skips) an async test no plugin ran, fail saying what to add.

    Every plugin runs first (anyio, pytest-asyncio, …): only pytest's own verdict is replaced.
    """
    try:
        return (yield)
    except (pytest.fail.Exception, pytest.skip.Exception) as exc:
        message = unrun_async_test_message(pyfuncitem)
        if message is None or _PYTESTS_WORDS not in str(exc):
            raise
        raise pytest.fail.Exception(message, pytrace=False) from None


def _sim_arguments(request: pytest.FixtureRequest, name: str = MARKER) -> dict[str, Any]:
    """The keyword arguments of the closest ``name`` marker."""
    marker = request.node.get_closest_marker(name)
    if marker is None:
        return {}
    if marker.args:
        raise pytest.UsageError(f"{name} takes keyword arguments only, got {marker.args!r}")
    return dict(marker.kwargs)


async def _no_leaks() -> AsyncIterator[None]:
    from galileo_async.testing.leaks import LeakCheck

    check = LeakCheck()
    yield
    problems = await check.finish()
    if problems:
        pytest.fail("the test left things behind:\n  " + "\n  ".join(problems), pytrace=False)


async def _checked(
    simulation: Callable[..., contextlib.AbstractAsyncContextManager[_Pair]],
    arguments: dict[str, Any],
) -> AsyncIterator[_Pair]:
    """``simulation(**arguments)`` for one test, with the leak check around it."""
    from galileo_async.testing.leaks import LeakCheck

    check = LeakCheck()
    async with simulation(**arguments) as pair:
        yield pair
        problems = await check.stop_tasks()  # before the Robots close under them
    problems += await check.finish()
    if problems:
        pytest.fail("the test left things behind:\n  " + "\n  ".join(problems), pytrace=False)


async def _simulation(
    request: pytest.FixtureRequest,
) -> AsyncIterator[tuple[Robot, SimulatedDevice]]:
    from galileo_async.testing.robot import simulated_robot

    async for pair in _checked(simulated_robot, _sim_arguments(request)):
        yield pair


async def _fleet_simulation(
    request: pytest.FixtureRequest,
) -> AsyncIterator[tuple[Fleet, dict[str, SimulatedDevice]]]:
    from galileo_async.testing.fleet import simulated_fleet

    async for pair in _checked(simulated_fleet, _sim_arguments(request, FLEET_MARKER)):
        yield pair


def _missing() -> Any:
    pytest.fail(
        "galileo_async's fixtures need pytest-asyncio: pip install 'galileo-async[testing]'",
        pytrace=False,
    )


galileo_simulation: Any
galileo_fleet_simulation: Any
galileo_no_leaks: Any
try:
    import pytest_asyncio
except ImportError:  # the plugin still loads; the fixtures say what is missing
    galileo_simulation = pytest.fixture(_missing, name="galileo_simulation")
    galileo_fleet_simulation = pytest.fixture(_missing, name="galileo_fleet_simulation")
    galileo_no_leaks = pytest.fixture(_missing, name="galileo_no_leaks")
else:
    #: ``(fleet, devices)`` of one simulated_fleet() per test (the galileo_fleet_sim marker's).
    galileo_fleet_simulation = pytest_asyncio.fixture(
        _fleet_simulation, name="galileo_fleet_simulation"
    )
    #: ``(robot, device)`` of one simulated_robot() per test (the galileo_sim marker's).
    galileo_simulation = pytest_asyncio.fixture(_simulation, name="galileo_simulation")
    #: Fails the test when it leaves a Robot, task or timer behind.
    galileo_no_leaks = pytest_asyncio.fixture(_no_leaks, name="galileo_no_leaks")


@pytest.fixture
def galileo_robot(galileo_simulation: tuple[Robot, SimulatedDevice]) -> Robot:
    """A Robot connected to a fresh simulated robot (navigation open), closed after the test."""
    return galileo_simulation[0]


@pytest.fixture
def galileo_device(galileo_simulation: tuple[Robot, SimulatedDevice]) -> SimulatedDevice:
    """The device side of galileo_robot's simulated robot: commands, faults, advance()."""
    return galileo_simulation[1]


@pytest.fixture
def galileo_fleet(
    galileo_fleet_simulation: tuple[Fleet, dict[str, SimulatedDevice]],
) -> Fleet:
    """A Fleet of fresh simulated robots (robot1, robot2, robot3 unless marked), closed after."""
    return galileo_fleet_simulation[0]


@pytest.fixture
def galileo_devices(
    galileo_fleet_simulation: tuple[Fleet, dict[str, SimulatedDevice]],
) -> dict[str, SimulatedDevice]:
    """The device side of each robot of galileo_fleet, by name."""
    return galileo_fleet_simulation[1]
