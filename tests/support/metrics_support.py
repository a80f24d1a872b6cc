"""The metrics tests' helpers: samples of a collector, promtool, and a real Prometheus."""

from __future__ import annotations

import asyncio
import contextlib
import json
import shutil
import socket
import subprocess
import tempfile
import time
import urllib.parse
import urllib.request
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from prometheus_client.registry import Collector

from tests.support.peers import missing_peer

__all__ = [
    "WAIT",
    "fetch_json",
    "free_port",
    "prometheus",
    "query",
    "require_prometheus",
    "require_promtool",
    "sample",
    "samples",
]

#: Real seconds a wait on a real peer may take (Prometheus starts, scrapes, answers).
WAIT = 60.0


def samples(collector: Collector) -> dict[tuple[str, tuple[tuple[str, str], ...]], float]:
    """Every sample of ``collector`` now: (name, sorted labels) → value."""
    return {
        (s.name, tuple(sorted(s.labels.items()))): s.value
        for family in collector.collect()
        for s in family.samples
    }


def sample(collector: Collector, name: str, **labels: str) -> float | None:
    """The value of sample ``name`` with exactly ``labels``, None if there is none."""
    return samples(collector).get((name, tuple(sorted(labels.items()))))


def require_promtool() -> str:
    """The promtool executable (Debian's prometheus); skip or fail as peers.missing_peer."""
    found = shutil.which("promtool")
    if found is None:
        missing_peer("promtool (Prometheus)")
    assert found is not None
    return found


def require_prometheus() -> str:
    """The prometheus executable (Debian's prometheus); skip or fail as peers.missing_peer."""
    found = shutil.which("prometheus")
    if found is None:
        missing_peer("Prometheus")
    assert found is not None
    return found


def free_port() -> int:
    """A loopback port free a moment ago (for a peer that must bind it itself)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


@contextlib.contextmanager
def prometheus(targets: list[str], *, interval: float = 1.0) -> Iterator[str]:
    """A real Prometheus on a free loopback port scraping ``targets`` (host:port); its URL.

    Its config and storage are in a temporary directory; the process is killed and
    waited for on every exit path.
    """
    executable = require_prometheus()
    with tempfile.TemporaryDirectory(prefix="galileo-prometheus-") as tmp:
        directory = Path(tmp)
        config = directory / "prometheus.yml"
        config.write_text(
            json.dumps(  # JSON is YAML
                {
                    "global": {"scrape_interval": f"{interval:g}s"},
                    "scrape_configs": [
                        {"job_name": "galileo", "static_configs": [{"targets": targets}]}
                    ],
                }
            )
        )
        port = free_port()
        log = (directory / "prometheus.log").open("wb")
        process = subprocess.Popen(
            [
                executable,
                f"--config.file={config}",
                f"--storage.tsdb.path={directory / 'data'}",
                f"--web.listen-address=127.0.0.1:{port}",
            ],
            stdout=log,
            stderr=subprocess.STDOUT,
        )
        try:
            yield f"http://127.0.0.1:{port}"
        except BaseException:
            log.flush()
            print((directory / "prometheus.log").read_text(errors="replace")[-4000:])
            raise
        finally:
            process.kill()
            process.wait(timeout=WAIT)
            log.close()


def fetch_json(url: str) -> Any:
    """GET ``url`` (blocking; loopback) and parse its JSON."""
    with urllib.request.urlopen(url, timeout=5) as answer:
        return json.loads(answer.read())


async def query(base: str, promql: str, *, until_series: int, wait: float = WAIT) -> list[Any]:
    """Poll /api/v1/query for ``promql`` until it has ``until_series`` series (bounded)."""
    url = f"{base}/api/v1/query?{urllib.parse.urlencode({'query': promql})}"
    deadline = time.monotonic() + wait
    last: Any = None
    while time.monotonic() < deadline:
        try:
            last = await asyncio.to_thread(fetch_json, url)
        except OSError as exc:  # not listening yet
            last = exc
        else:
            result: list[Any] = last["data"]["result"]
            if len(result) >= until_series:
                return result
        await asyncio.sleep(0.5)
    raise AssertionError(f"{promql}: not {until_series} series within {wait} s: {last!r}")
