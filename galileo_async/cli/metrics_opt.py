"""``--metrics [HOST:]PORT`` of the long-running commands: Prometheus metrics while they run."""

from __future__ import annotations

import contextlib
from collections.abc import AsyncIterator, Callable, Mapping
from typing import TYPE_CHECKING, Annotated, NoReturn

import anyio
import typer

from .output import err_console

if TYPE_CHECKING:
    from ..metrics import Metrics
    from ..robot import Robot

__all__ = ["MetricsAddress", "MetricsOption", "follow_robots", "metrics_address", "metrics_served"]

#: Where to serve: (host, port).
MetricsAddress = tuple[str, int]

#: The --metrics option (parse it with metrics_address before anything connects).
MetricsOption = Annotated[
    str | None,
    typer.Option(
        "--metrics",
        metavar="[HOST:]PORT",
        help="Serve Prometheus metrics at http://HOST:PORT/metrics while it runs "
        "(HOST: 127.0.0.1 unless given; 0.0.0.0 for every interface; needs the extra metrics).",
    ),
]

#: Seconds between two looks at a changing set of robots (follow_robots).
FOLLOW_PERIOD = 1.0


def metrics_address(value: str | None) -> MetricsAddress | None:
    """--metrics as (host, port), None when not given; a bad value or missing extra exits 2."""
    if value is None:
        return None
    try:
        import aiohttp  # noqa: F401
        import prometheus_client  # noqa: F401
    except ImportError:  # pragma: no cover - depends on the installed extras
        _usage("needs the extra: pip install 'galileo-async[metrics]'")
    from ..metrics import DEFAULT_METRICS_HOST

    host, colon, port_text = value.rpartition(":")
    if not colon:
        host = DEFAULT_METRICS_HOST
    host = host.removeprefix("[").removesuffix("]")  # [::1]:9464
    if colon and not host:
        _usage(f"{value!r}: the host is empty (give PORT or HOST:PORT)")
    if not port_text.isdigit() or not 0 < int(port_text) < 65536:
        _usage(f"{value!r}: the port must be a number 1-65535")
    return host, int(port_text)


def _usage(message: str) -> NoReturn:
    """A usage error of --metrics (exit 2, before anything connects)."""
    raise typer.BadParameter(message, param_hint="--metrics")


@contextlib.asynccontextmanager
async def metrics_served(address: MetricsAddress | None) -> AsyncIterator[Metrics | None]:
    """The endpoint at ``address`` while inside (None: no metrics, nothing served).

    Enter it before connecting: an address that cannot be bound raises OSError naming it
    before anything connects. The caller adds its robots or fleet to the Metrics it gives.
    """
    if address is None:
        yield None
        return
    from ..metrics import Metrics, serve_metrics

    metrics = Metrics()
    async with contextlib.AsyncExitStack() as stack:
        stack.callback(metrics.close)
        server = await stack.enter_async_context(serve_metrics(metrics, *address))
        err_console().print(f"metrics: {server.url}", markup=False, style="dim")
        yield metrics


async def follow_robots(metrics: Metrics, robots: Callable[[], Mapping[str, Robot]]) -> None:
    """Keep ``metrics`` following ``robots()`` (looked at every second) until cancelled."""
    followed: dict[str, Robot] = {}
    while True:
        now = robots()
        for name, robot in list(followed.items()):
            if now.get(name) is not robot:
                metrics.remove_robot(name)
                del followed[name]
        for name, robot in now.items():
            if name not in followed:
                metrics.add_robot(robot, name=name)
                followed[name] = robot
        await anyio.sleep(FOLLOW_PERIOD)
