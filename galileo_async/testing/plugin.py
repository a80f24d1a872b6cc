"""The pytest plugin (entry point pytest11): galileo_robot, galileo_device, the galileo_sim marker.

``galileo_robot`` and ``galileo_device`` are the two halves of one fresh
simulated_robot() per test, on a virtual clock; ``@pytest.mark.galileo_sim(...)`` passes
simulated_robot's arguments. A test that uses them fails when it leaves a Robot, task
or timer behind; ``galileo_no_leaks`` gives any async test the same check. The fixtures
need pytest-asyncio (the extra ``testing``); the plugin loads without it.
"""

from __future__ import annotations

from collections.abc import AsyncIterator
from typing import TYPE_CHECKING, Any

import pytest

if TYPE_CHECKING:
    from ..robot import Robot
    from .device import SimulatedDevice

__all__ = ["galileo_device", "galileo_no_leaks", "galileo_robot", "galileo_simulation"]

MARKER = "galileo_sim"
_MARKER_HELP = (
    f"{MARKER}(firmware='real', layout='v2', map_targets=None, targets=None, "
    "navigating=True, clock='virtual', sim_options=None, **connect_options): "
    "the simulated robot behind the galileo_robot and galileo_device fixtures"
)


def pytest_configure(config: pytest.Config) -> None:
    """Declare the marker (so --strict-markers accepts it)."""
    config.addinivalue_line("markers", _MARKER_HELP)


def _sim_arguments(request: pytest.FixtureRequest) -> dict[str, Any]:
    """simulated_robot's arguments from the closest galileo_sim marker."""
    marker = request.node.get_closest_marker(MARKER)
    if marker is None:
        return {}
    if marker.args:
        raise pytest.UsageError(f"{MARKER} takes keyword arguments only, got {marker.args!r}")
    return dict(marker.kwargs)


async def _no_leaks() -> AsyncIterator[None]:
    from .leaks import LeakCheck

    check = LeakCheck()
    yield
    problems = await check.finish()
    if problems:
        pytest.fail("the test left things behind:\n  " + "\n  ".join(problems), pytrace=False)


async def _simulation(
    request: pytest.FixtureRequest,
) -> AsyncIterator[tuple[Robot, SimulatedDevice]]:
    from .leaks import LeakCheck
    from .robot import simulated_robot

    check = LeakCheck()
    async with simulated_robot(**_sim_arguments(request)) as pair:
        yield pair
        problems = await check.stop_tasks()  # before the Robot closes under them
    problems += await check.finish()
    if problems:
        pytest.fail("the test left things behind:\n  " + "\n  ".join(problems), pytrace=False)


def _missing() -> Any:
    pytest.fail(
        "galileo_async's fixtures need pytest-asyncio: pip install 'galileo-async[testing]'",
        pytrace=False,
    )


galileo_simulation: Any
galileo_no_leaks: Any
try:
    import pytest_asyncio
except ImportError:  # the plugin still loads; the fixtures say what is missing
    galileo_simulation = pytest.fixture(_missing, name="galileo_simulation")
    galileo_no_leaks = pytest.fixture(_missing, name="galileo_no_leaks")
else:
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
