"""https:// and wss:// against the simulator's HTTP face over TLS (a test CA), on loopback."""

from __future__ import annotations

import asyncio
import contextlib
import ssl
import subprocess
import sys
from collections.abc import AsyncIterator
from pathlib import Path
from typing import Any

import pytest

import galileo_async as galileo
from galileo_async import GalileoConnectionError, InvalidArgument, TargetStatus
from galileo_async.sim import Simulator
from tests.support.vda5050_support import MutualTls, make_mutual_tls

pytestmark = pytest.mark.timeout(60)

WAIT = 10.0
TARGETS = ((1.5, 0.0), (30.0, 0.0))


@pytest.fixture(name="tls", scope="module")
def tls_fixture(tmp_path_factory: pytest.TempPathFactory) -> MutualTls:
    """A test CA and a server certificate for 127.0.0.1 it signed."""
    return make_mutual_tls(tmp_path_factory.mktemp("tls"))


def server_context(tls: MutualTls) -> ssl.SSLContext:
    context = ssl.create_default_context(ssl.Purpose.CLIENT_AUTH)
    context.load_cert_chain(str(tls.server_cert), str(tls.server_key))
    return context


@contextlib.asynccontextmanager
async def tls_face(tls: MutualTls) -> AsyncIterator[tuple[Simulator, Any, str]]:
    """A simulator serving REST and the WebSocket over TLS, its face and the https:// URL."""
    async with Simulator(speed=40.0, targets=TARGETS) as sim:
        face = await sim.serve_http(ssl_context=server_context(tls))
        yield sim, face, f"https://127.0.0.1:{face.address[1]}?ws_port={face.ws_address[1]}"


async def test_https_and_wss_with_the_ca_file_status_goto_cancel(tls: MutualTls) -> None:
    async with (
        tls_face(tls) as (sim, face, url),
        galileo.connect(url, ca_file=str(tls.ca), map_targets=len(TARGETS)) as robot,
    ):
        status = await robot.wait_until(lambda s: s.power is not None, timeout=WAIT)
        assert status.power == pytest.approx(sim.state.status.power)
        assert face.sockets  # the status came over wss://: the face speaks only TLS
        await robot.start_navigation(timeout=WAIT)
        result = await robot.goto(0, timeout=WAIT)
        assert result.target_id == 0
        far = asyncio.ensure_future(robot.goto(1, timeout=WAIT))
        await robot.wait_until(lambda s: s.target_status == TargetStatus.WORKING, timeout=WAIT)
        await robot.cancel(timeout=WAIT)
        with pytest.raises(galileo.GoalCancelled):
            await far
        assert [task["state"] for task in face.tasks.values()] == ["COMPLETE", "CANCELLED"]


@pytest.mark.parametrize("login", [{}, {"username": "admin", "password": "admin"}])
async def test_without_the_ca_the_certificate_is_refused_and_nothing_sent(
    tls: MutualTls, login: dict[str, str]
) -> None:
    async with tls_face(tls) as (sim, face, url):
        with pytest.raises(GalileoConnectionError, match="certificate verify failed") as caught:
            async with galileo.connect(url, connect_timeout=2.0, **login):
                pass
        assert "admin" not in str(caught.value) or not login
        assert face.requests == 0
        assert not face.sockets
        assert sim.state.status.target_status != TargetStatus.WORKING


async def test_a_ca_that_did_not_sign_the_server_is_refused(tls: MutualTls, tmp_path: Path) -> None:
    other = make_mutual_tls(tmp_path)
    async with tls_face(tls) as (_sim, face, url):
        with pytest.raises(GalileoConnectionError, match="certificate verify failed"):
            async with galileo.connect(url, ca_file=other.ca, connect_timeout=2.0):
                pass
        assert face.requests == 0


@pytest.mark.parametrize(
    ("url", "value", "words"),
    [
        ("https://127.0.0.1:1", "/nonexistent/ca.pem", "not a readable file"),
        ("https://127.0.0.1:1", 5, "PEM CA file"),
        ("http://127.0.0.1:1", __file__, "https:// only"),
    ],
)
def test_bad_ca_file_is_invalid_before_anything_opens(url: str, value: object, words: str) -> None:
    with pytest.raises(InvalidArgument, match=words):
        galileo.connect(url, ca_file=value)


def test_cli_sim_over_tls_and_status_with_ca_file_in_the_url(tls: MutualTls) -> None:
    sim = subprocess.Popen(
        [sys.executable, "-m", "galileo_async", "sim", "--http", "0", "--ws-port", "0",
         "--tls-cert", str(tls.server_cert), "--tls-key", str(tls.server_key)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )  # fmt: skip
    try:
        assert sim.stdout is not None
        url = sim.stdout.readline().strip()
        assert url.startswith("https://127.0.0.1:"), url
        status = [sys.executable, "-m", "galileo_async", "-p"]
        trusted = subprocess.run(
            [*status, f"{url}{'&' if '?' in url else '?'}ca_file={tls.ca}", "status", "--json"],
            capture_output=True, text=True, timeout=WAIT * 3,
        )  # fmt: skip
        assert trusted.returncode == 0, trusted.stderr
        assert '"layout": "ros"' in trusted.stdout
        refused = subprocess.run(
            [*status, url, "status", "--json"], capture_output=True, text=True, timeout=WAIT * 3
        )
        assert refused.returncode != 0
        assert "certificate verify failed" in refused.stdout + refused.stderr
    finally:
        sim.terminate()
        sim.communicate(timeout=WAIT)


def test_cli_sim_tls_needs_both_files_and_http(tls: MutualTls) -> None:
    result = subprocess.run(
        [sys.executable, "-m", "galileo_async", "sim", "--http", "0",
         "--tls-cert", str(tls.server_cert)],
        capture_output=True, text=True, timeout=WAIT * 3,
    )  # fmt: skip
    assert result.returncode != 0
    assert "--tls-cert and --tls-key go together" in result.stdout + result.stderr
