"""simulated_robot(): a connected Robot and the device side of the same simulated robot."""

from __future__ import annotations

import contextlib
import math
import sys
from collections.abc import AsyncIterator, Mapping, Sequence
from typing import TYPE_CHECKING, Any, Literal

from .._checks import check_bool, check_int, check_number
from ..errors import InvalidArgument
from ..robot import Robot, connect
from ..sim import DEFAULT_TARGETS, Simulator
from .clock import VirtualClock
from .device import SimulatedDevice

if TYPE_CHECKING:
    from ..options import ConnectOptions

    if sys.version_info >= (3, 11):
        from typing import Unpack
    else:
        from typing_extensions import Unpack

__all__ = ["Clock", "SimLink", "build_simulator", "map_of", "simulated_robot"]

#: "virtual": time jumps ahead whenever the loop is idle (VirtualClock); "real": wall time.
Clock = Literal["virtual", "real"]
#: "sim": the in-process link (sim://); "http": the simulator's HTTP face on loopback.
SimLink = Literal["sim", "http"]


def map_of(count: int) -> tuple[tuple[float, float], ...]:
    """The simulator's default map cut or extended to ``count`` targets (4 m ring beyond 6)."""
    check_int("map_targets", count, 0, 255)
    extra = count - len(DEFAULT_TARGETS)
    ring = tuple(
        (
            round(4.0 * math.cos(math.tau * i / extra), 3),
            round(4.0 * math.sin(math.tau * i / extra), 3),
        )
        for i in range(max(0, extra))
    )
    return (DEFAULT_TARGETS + ring)[:count]


def _points(targets: Sequence[tuple[float, float]]) -> tuple[tuple[float, float], ...]:
    """``targets`` as (x, y) pairs of finite floats; InvalidArgument for anything else."""
    try:
        return tuple((check_number("x", x), check_number("y", y)) for x, y in targets)
    except (TypeError, ValueError):  # InvalidArgument is a ValueError
        raise InvalidArgument(
            f"targets must be (x, y) pairs of finite numbers, got {targets!r}"
        ) from None


@contextlib.asynccontextmanager
async def simulated_robot(
    *,
    firmware: Literal["real", "document"] = "real",
    targets: Sequence[tuple[float, float]] | None = None,
    navigating: bool = True,
    clock: Clock = "virtual",
    sim_options: Mapping[str, Any] | None = None,
    link: SimLink = "sim",
    **options: Unpack[ConnectOptions],
) -> AsyncIterator[tuple[Robot, SimulatedDevice]]:
    """``async with simulated_robot() as (robot, device)``: a Robot on a simulated robot.

    ``firmware``: the simulated robot's ("real" or "document", docs/protocol.md); ``layout``
    (an option): its status layout, default "v2" (the Robot detects it, as on a real
    port); ``map_targets`` (an option): its map size (default 6, or ``len(targets)``), and
    the Robot's; ``targets``: the map's (x, y) points;
    ``navigating``: navigation already open and tracking, as on a robot in service (no
    command sent); ``clock``: "virtual" (VirtualClock on the running loop: driver timers and
    the robot on one clock that jumps when idle) or "real"; ``sim_options``: more
    galileo_async.sim.SimConfig fields (``seed``, ``start_pose``, fault names …);
    ``link``: "sim" (in-process) or "http" (the simulator's HTTP face on loopback: the
    Robot has ``robot.http``; needs aiohttp); ``options``: connect()'s. Everything is
    checked before anything starts (InvalidArgument); on exit the Robot, the simulator
    and the clock are released.
    """
    connect_options: dict[str, Any] = dict(options)
    if link not in ("sim", "http"):
        raise InvalidArgument(f"link must be 'sim' or 'http', got {link!r}")
    simulator = build_simulator(
        firmware=firmware, targets=targets, navigating=navigating, clock=clock,
        sim_options=sim_options, options=connect_options,
    )  # fmt: skip
    virtual = VirtualClock.install() if clock == "virtual" else None
    try:
        async with simulator:
            device = SimulatedDevice(simulator, virtual)
            url = simulator.url
            if link == "http":
                face = device.http_face = await simulator.serve_http(ws_port=0)
                url = f"http://127.0.0.1:{face.address[1]}?ws_port={face.ws_address[1]}"
            async with connect(url, **connect_options) as robot:
                yield robot, device
    finally:
        if virtual is not None:
            virtual.release()


def build_simulator(
    *,
    firmware: str,
    targets: Sequence[tuple[float, float]] | None,
    navigating: bool,
    clock: str,
    sim_options: Mapping[str, Any] | None,
    options: dict[str, Any],
) -> Simulator:
    """The Simulator simulated_robot() describes; ``options`` loses layout, gains map_targets.

    InvalidArgument, nothing started, for any argument out of place.
    """
    check_bool("navigating", navigating)
    layout = options.pop("layout", None) or "v2"
    map_targets = options.get("map_targets")
    if clock not in ("virtual", "real"):
        raise InvalidArgument(f"clock must be 'virtual' or 'real', got {clock!r}")
    if targets is not None:
        targets = _points(targets)
        if map_targets is not None and map_targets != len(targets):
            raise InvalidArgument(
                f"map_targets={map_targets} contradicts the {len(targets)} targets given"
            )
    else:
        targets = map_of(6 if map_targets is None else map_targets)
    if not isinstance(sim_options, (Mapping, type(None))):
        raise InvalidArgument(
            f"sim_options must be a mapping of SimConfig fields, got {sim_options!r}"
        )
    extra = dict(sim_options or {})
    for name in ("firmware", "layout", "targets"):
        if name in extra:
            raise InvalidArgument(f"pass {name} as simulated_robot's own argument")
    if clock == "virtual" and "speed" in extra:
        raise InvalidArgument("speed: a virtual clock runs the robot as fast as it can already")
    simulator = Simulator(firmware=firmware, layout=layout, targets=targets, **extra)
    options["map_targets"] = len(targets)
    if navigating:
        simulator.model.open_navigation()
    return simulator
