"""serve_metrics: GET /metrics on the event loop (aiohttp.web), in the format asked for."""

from __future__ import annotations

import asyncio
import os
from collections.abc import AsyncIterator, Awaitable, Callable, Iterable
from contextlib import asynccontextmanager
from dataclasses import dataclass

from aiohttp import web
from prometheus_client.exposition import choose_encoder
from prometheus_client.metrics_core import Metric
from prometheus_client.registry import Collector, CollectorRegistry

from ..robot.runtime import finish_shielded

__all__ = ["DEFAULT_METRICS_HOST", "DEFAULT_METRICS_PORT", "MetricsServer", "serve_metrics"]

#: Loopback only unless the caller names another host.
DEFAULT_METRICS_HOST = "127.0.0.1"
#: The port `galileo ... --metrics` and serve_metrics use when none is given.
DEFAULT_METRICS_PORT = 9464
#: Longest a closing endpoint waits for a scrape still being answered.
_SHUTDOWN_TIMEOUT = 1.0


@dataclass(frozen=True, slots=True)
class MetricsServer:
    """Where the endpoint listens: ``url`` is its GET /metrics (``port`` the bound one)."""

    host: str
    port: int
    registry: CollectorRegistry

    @property
    def url(self) -> str:
        """The scrape URL, e.g. ``http://127.0.0.1:9464/metrics``."""
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"http://{host}:{self.port}/metrics"


class _Snapshot(Collector):
    """Metrics one scrape collected (plain values), for an encoder that wants a collector."""

    def __init__(self, families: list[Metric]) -> None:
        self._families = families

    def collect(self) -> Iterable[Metric]:
        return self._families


#: How an OpenMetrics exposition ends; encoded family by family, only the last keeps it.
_EOF = b"# EOF\n"


async def _encode(
    encoder: Callable[[Collector], bytes], families: Iterable[Metric], openmetrics: bool
) -> bytes:
    """Each of ``families`` read and encoded in turn, the loop running between two (a family
    of 1000 robots takes tens of ms; a worker thread would hold the GIL against the loop)."""
    parts = []
    for family in families:
        part = encoder(_Snapshot([family]))
        parts.append(part.removesuffix(_EOF) if openmetrics else part)
        await asyncio.sleep(0)
    if openmetrics:
        parts.append(_EOF)
    return b"".join(parts)


def _handler(registry: CollectorRegistry) -> Callable[[web.Request], Awaitable[web.Response]]:
    async def metrics(request: web.Request) -> web.Response:
        # OpenMetrics text when the Accept header asks for it, else the Prometheus text.
        encoder, content_type = choose_encoder(request.headers.get("Accept", ""))
        openmetrics = content_type.startswith("application/openmetrics-text")
        # The robots are read on their loop, family by family, as the encoding reaches them.
        body = await _encode(encoder, registry.collect(), openmetrics)
        return web.Response(body=body, headers={"Content-Type": content_type})

    return metrics


@asynccontextmanager
async def serve_metrics(
    metrics: Collector,
    host: str = DEFAULT_METRICS_HOST,
    port: int = DEFAULT_METRICS_PORT,
) -> AsyncIterator[MetricsServer]:
    """Serve ``metrics`` (a Metrics, or any collector) at http://host:port/metrics while open.

    Each scrape reads and encodes one metric of every robot at a time, on this event loop,
    letting the loop run between two. Port 0 binds a free port (see ``.port``); an
    address that cannot be bound (in use, not local) raises OSError naming it, and leaving
    the block, however it is left, closes the endpoint within about a second.
    """
    registry = CollectorRegistry(auto_describe=False)
    registry.register(metrics)
    app = web.Application()
    app.router.add_get("/metrics", _handler(registry))
    runner = web.AppRunner(
        app, handle_signals=False, access_log=None, shutdown_timeout=_SHUTDOWN_TIMEOUT
    )
    await runner.setup()
    try:
        site = web.TCPSite(runner, host, port)
        try:
            await site.start()
        except OSError as exc:
            why = os.strerror(exc.errno) if exc.errno else str(exc)
            raise OSError(exc.errno, f"cannot serve metrics on {host}:{port}: {why}") from exc
        server = site._server  # the one asyncio.Server a TCPSite holds
        assert isinstance(server, asyncio.Server)
        bound: int = server.sockets[0].getsockname()[1]
        yield MetricsServer(host, bound, registry)
    finally:
        cleanup = asyncio.ensure_future(runner.cleanup())
        await finish_shielded(cleanup, "closing the metrics endpoint")
