"""serve_metrics on 127.0.0.1 (real clock): formats, content negotiation, errors, every exit."""

from __future__ import annotations

import asyncio
import socket
import subprocess

import aiohttp
import pytest

from galileo_async.metrics import Metrics, serve_metrics
from galileo_async.testing import simulated_fleet
from tests.support.cancel_ways import WAYS, stop_waiting
from tests.support.metrics_support import (
    WAIT,
    fetch_json,
    prometheus,
    query,
    require_promtool,
)

OPENMETRICS = "application/openmetrics-text; version=1.0.0; charset=utf-8"
#: Real seconds a scrape on loopback may take.
STEP = 10.0


async def scrape(url: str, accept: str | None = None) -> tuple[str, str]:
    """GET ``url`` with ``accept``: (Content-Type, body)."""
    headers = {} if accept is None else {"Accept": accept}
    timeout = aiohttp.ClientTimeout(total=STEP)
    async with (
        aiohttp.ClientSession(timeout=timeout) as session,
        session.get(url, headers=headers) as answer,
    ):
        assert answer.status == 200
        return answer.headers["Content-Type"], await answer.text()


def check_metrics(promtool: str, text: str) -> subprocess.CompletedProcess[str]:
    """``promtool check metrics`` on ``text``."""
    return subprocess.run(
        [promtool, "check", "metrics"], input=text, capture_output=True, text=True, timeout=WAIT
    )


def refused(port: int) -> bool:
    """True when nothing listens on 127.0.0.1:``port``."""
    with socket.socket() as probe:
        return probe.connect_ex(("127.0.0.1", port)) != 0


async def test_both_text_formats_by_the_accept_header() -> None:
    async with simulated_fleet(2, clock="real") as (fleet, _devices):
        metrics = Metrics()
        metrics.add_fleet(fleet)
        try:
            async with serve_metrics(metrics, port=0) as server:
                assert server.host == "127.0.0.1"
                assert server.url == f"http://127.0.0.1:{server.port}/metrics"
                kind, text = await scrape(server.url)
                assert kind.startswith("text/plain; version=0.0.4")
                assert 'galileo_frames_received_total{robot="robot1"}' in text
                assert "# EOF" not in text
                kind, text = await scrape(server.url, OPENMETRICS)
                assert kind.startswith("application/openmetrics-text; version=1.0.0")
                assert "# TYPE galileo_frames_received counter" in text
                assert text.endswith("# EOF\n")
        finally:
            metrics.close()


async def test_promtool_checks_the_exposition() -> None:
    promtool = require_promtool()
    async with simulated_fleet(3, clock="real") as (fleet, _devices):
        metrics = Metrics()
        metrics.add_fleet(fleet)
        try:
            await fleet["robot2"].goto(1)
            async with serve_metrics(metrics, port=0) as server:
                _kind, text = await scrape(server.url)
                _kind, open_text = await scrape(server.url, OPENMETRICS)
        finally:
            metrics.close()
    checked = await asyncio.to_thread(check_metrics, promtool, text)
    assert checked.returncode == 0, checked.stdout + checked.stderr
    assert checked.stdout + checked.stderr == ""  # no lint remark either
    # promtool's check reads the Prometheus text format only (it knows no "stateset" type):
    # the OpenMetrics text is read by a real Prometheus (test_a_real_prometheus_scrapes_a_fleet).
    checked = await asyncio.to_thread(check_metrics, promtool, open_text)
    assert "stateset" in checked.stderr


async def test_a_port_in_use_is_a_clear_error() -> None:
    with socket.socket() as holder:
        holder.bind(("127.0.0.1", 0))
        holder.listen()
        port = holder.getsockname()[1]
        with pytest.raises(OSError, match=f"cannot serve metrics on 127.0.0.1:{port}"):
            async with serve_metrics(Metrics(), port=port):
                pytest.fail("served on a port in use")


@pytest.mark.parametrize("how", WAYS)
async def test_every_way_out_closes_the_endpoint(how: str) -> None:
    ports: list[int] = []
    serving = asyncio.Event()

    async def serve() -> None:
        async with serve_metrics(Metrics(), port=0) as server:
            ports.append(server.port)
            await scrape(server.url)
            serving.set()
            await asyncio.sleep(3600)

    await stop_waiting(how, serve, 0.5)
    assert serving.is_set()
    assert refused(ports[0])  # and the leak check finds no task or timer left


async def test_a_real_prometheus_scrapes_a_fleet() -> None:
    async with simulated_fleet(3, clock="real") as (fleet, _devices):
        metrics = Metrics()
        metrics.add_fleet(fleet)
        try:
            async with serve_metrics(metrics, port=0) as server:
                with prometheus([f"127.0.0.1:{server.port}"]) as base:
                    series = await query(base, "galileo_frames_received_total", until_series=3)
                    assert {s["metric"]["robot"] for s in series} == {
                        "robot1", "robot2", "robot3"
                    }  # fmt: skip
                    assert all(float(s["value"][1]) > 0 for s in series)
                    up = await query(base, 'galileo_link_state{galileo_link_state="up"} == 1',
                                     until_series=3)  # fmt: skip
                    assert len(up) == 3
                    health = await query(base, 'up{job="galileo"} == 1', until_series=1)
                    assert len(health) == 1
                    # It asks for OpenMetrics first: what it read was that format.
                    meta = await asyncio.to_thread(
                        fetch_json, f"{base}/api/v1/targets/metadata?metric=galileo_link_state"
                    )
                    assert {m["type"] for m in meta["data"]} == {"stateset"}
        finally:
            metrics.close()
