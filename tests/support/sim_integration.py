"""A real Robot connected to a real Simulator over TCP loopback or a pty: the shared harness.

The integration tests (``test_integration_*.py``) run every operation against this pair.
Their matrix is ``MODES``: the 8 (firmware, layout) pairs, each served over one transport
so that every layout and every firmware mode is seen over both TCP and the pty::

    firmware  layout        transport
    real      v2            tcp
    real      v2_truncated  pty
    real      v1            tcp
    real      v1_charge     pty
    document  v2            pty
    document  v2_truncated  tcp
    document  v1            pty
    document  v1_charge     tcp

Every operation test runs over all 8 pairs (16 → 8 by pairing the transport with the
layout and firmware instead of crossing it), and asserts what the pair can show: the
effect in the robot's status where the layout has the field, else the documented
``UnconfirmedOperation`` or None, with the simulator's own state as the witness that the
command did reach the robot. The simulator runs ``SPEED`` times faster than real time.
"""

from __future__ import annotations

import asyncio
import contextlib
import math
import sys
from collections.abc import AsyncIterator, Callable
from dataclasses import dataclass
from typing import Any

import anyio
import pytest

import galileo_async as galileo
from galileo_async.models import GalileoStatus, StatusLayout
from galileo_async.protocol import LAYOUTS, UDP_LAYOUTS, Command
from galileo_async.sim import SimState, Simulator

__all__ = [
    "FAR",
    "INVALID_ID",
    "MAP_TARGETS",
    "MODES",
    "NEAR",
    "RIGHT",
    "SPEED",
    "TARGETS",
    "WAIT",
    "Mode",
    "modes",
    "near",
    "record_commands",
    "robot_on_sim",
    "sim_reaches",
    "sim_seconds",
    "speeds_of",
    "time_limit",
]

#: Simulated seconds per real second.
SPEED = 80.0
#: Bound, in real seconds, on every wait that is expected to succeed.
WAIT = 10.0
#: The map: a target 1.5 m straight ahead, one 30 m ahead (a long trip to interrupt), and
#: one 2 m to the right (the robot turns first).
TARGETS: tuple[tuple[float, float], ...] = ((1.5, 0.0), (30.0, 0.0), (0.0, -2.0))
NEAR, FAR, RIGHT = 0, 1, 2
MAP_TARGETS = len(TARGETS)
#: A goal id the map does not have.
INVALID_ID = 77


def sim_seconds(seconds: float) -> float:
    """Real seconds that ``seconds`` of simulated time take."""
    return seconds / SPEED


@dataclass(frozen=True)
class Mode:
    """One cell of the matrix: firmware mode, status layout and transport."""

    firmware: str
    layout: StatusLayout
    transport: str

    @property
    def id(self) -> str:
        """pytest id."""
        return f"{self.firmware}-{self.layout.value}-{self.transport}"

    @property
    def real(self) -> bool:
        """True for the published firmware's behaviour."""
        return self.firmware == "real"

    def has(self, field: str) -> bool:
        """Whether this layout's frames carry ``field``."""
        layout = LAYOUTS.get(self.layout) or UDP_LAYOUTS[self.layout]
        return field in layout.fields


MODES: tuple[Mode, ...] = (
    Mode("real", StatusLayout.V2, "tcp"),
    Mode("real", StatusLayout.V2_TRUNCATED, "pty"),
    Mode("real", StatusLayout.V1, "tcp"),
    Mode("real", StatusLayout.V1_CHARGE, "pty"),
    Mode("document", StatusLayout.V2, "pty"),
    Mode("document", StatusLayout.V2_TRUNCATED, "tcp"),
    Mode("document", StatusLayout.V1, "pty"),
    Mode("document", StatusLayout.V1_CHARGE, "tcp"),
    # The robot's UDP port (docs/protocol.md §7): its own 48-byte layout, real firmware only.
    Mode("real", StatusLayout.UDP_V2, "udp"),
)


def modes(where: Callable[[Mode], bool] = lambda mode: True) -> pytest.MarkDecorator:
    """``pytest.mark.parametrize`` over the MODES for which ``where`` holds."""
    chosen = [pytest.param(mode, id=mode.id) for mode in MODES if where(mode)]
    return pytest.mark.parametrize("mode", chosen)


@contextlib.asynccontextmanager
async def robot_on_sim(
    mode: Mode,
    *,
    navigate: bool = True,
    robot_options: dict[str, Any] | None = None,
    **sim_options: Any,
) -> AsyncIterator[tuple[Simulator, galileo.Robot]]:
    """A Simulator served over ``mode.transport`` and a Robot connected to it by URL.

    With ``navigate`` the robot has navigation open and the visual system initialised.
    """
    options: dict[str, Any] = {"speed": SPEED, "targets": TARGETS, **sim_options}
    if mode.transport == "udp":
        options["udp_layout"] = mode.layout
    else:
        options["layout"] = mode.layout
    async with Simulator(firmware=mode.firmware, **options) as sim:
        if mode.transport == "udp":
            face = await sim.serve_udp()
            url = f"udp://127.0.0.1:{face.address[1]}"
        elif mode.transport == "tcp":
            server = await sim.serve_tcp()
            url = f"socket://127.0.0.1:{server.sockets[0].getsockname()[1]}"
        else:
            url = sim.open_pty()
        connect_options: dict[str, Any] = {"map_targets": MAP_TARGETS, **(robot_options or {})}
        async with galileo.connect(url, **connect_options) as robot:
            # Auto-detection must find the simulator's layout (docs/protocol.md §1).
            assert robot.link.layout is mode.layout
            if navigate:
                await robot.start_navigation(timeout=WAIT)
            yield sim, robot


async def sim_reaches(
    robot: galileo.Robot, sim: Simulator, predicate: Callable[[SimState], bool]
) -> GalileoStatus:
    """Wait, frame by frame, until ``predicate`` holds for the simulator's own state."""
    state = sim.state
    return await robot.wait_until(lambda _status: predicate(state), timeout=WAIT)


def near(value: float | None, expected: float, tolerance: float = 1e-3) -> bool:
    """``value`` is a number within ``tolerance`` of ``expected``."""
    return value is not None and math.isclose(value, expected, abs_tol=tolerance)


def time_limit(seconds: float) -> contextlib.AbstractAsyncContextManager[object]:
    """``asyncio.timeout`` (Python 3.11+), else the same behaviour from anyio."""
    if sys.version_info >= (3, 11):
        return asyncio.timeout(seconds)
    return _anyio_time_limit(seconds)


@contextlib.asynccontextmanager
async def _anyio_time_limit(seconds: float) -> AsyncIterator[None]:
    with anyio.fail_after(seconds):
        yield


def record_commands(sim: Simulator) -> list[tuple[Command, bool]]:
    """Log every command the simulated robot receives, with whether it was busy then."""
    log: list[tuple[Command, bool]] = []
    model = sim.model
    submit = model.submit

    def recording(command: Command) -> None:
        log.append((command, model.busy))
        submit(command)

    model.submit = recording  # type: ignore[method-assign]
    return log


@contextlib.asynccontextmanager
async def speeds_of(robot: galileo.Robot) -> AsyncIterator[list[float]]:
    """The linear speeds of every status received meanwhile."""
    speeds: list[float] = []

    async def watch() -> None:
        async for status in robot.statuses():
            speeds.append(abs(status.current_speed_x or 0.0))

    watcher = asyncio.ensure_future(watch())
    try:
        yield speeds
    finally:
        watcher.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await watcher
