"""http:// failures have types a user can catch and messages that say why and where."""

from __future__ import annotations

import asyncio
import contextlib
import socket
import time
from collections.abc import AsyncIterator

import pytest
from aiohttp import web

import galileo_async as galileo
from galileo_async import AuthenticationError, GalileoTimeout, HttpError, HttpTimeout
from galileo_async.http import HttpApi
from galileo_async.sim import Simulator
from tests.links.test_http_link import http_of

pytestmark = pytest.mark.timeout(60)


def free_port() -> int:
    """A loopback TCP port nothing listens on (bound, then released)."""
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        port: int = sock.getsockname()[1]
    return port


@contextlib.asynccontextmanager
async def silent_server(path: str) -> AsyncIterator[int]:
    """A server on 127.0.0.1 whose handler of ``path`` never answers; yields its port."""
    release = asyncio.Event()

    async def silent(request: web.Request) -> web.Response:
        await release.wait()
        return web.Response(status=503)

    app = web.Application()
    app.add_routes([web.get(path, silent)])
    runner = web.AppRunner(app, handle_signals=False, access_log=None)
    await runner.setup()
    site = web.TCPSite(runner, "127.0.0.1", 0)
    await site.start()
    try:
        yield site._server.sockets[0].getsockname()[1]  # type: ignore[union-attr]
    finally:
        release.set()
        await runner.cleanup()


def test_the_error_types_catch_as_documented() -> None:
    assert issubclass(HttpTimeout, HttpError)
    assert issubclass(HttpTimeout, GalileoTimeout)
    assert issubclass(HttpTimeout, TimeoutError)
    assert issubclass(AuthenticationError, HttpError)
    assert issubclass(AuthenticationError, galileo.GalileoConnectionError)
    assert not issubclass(AuthenticationError, TimeoutError)
    timeout = HttpTimeout("GET /api/v1/x: no answer", endpoint="/x")
    assert (timeout.endpoint, timeout.status) == ("/x", None)


async def test_a_rest_call_without_an_answer_is_a_timeout_error() -> None:
    async with silent_server("/api/v1/system/info") as port:
        api = HttpApi(f"http://127.0.0.1:{port}", timeout=0.3)
        try:
            with pytest.raises(TimeoutError) as info:
                await api.call("GET", "/system/info")
        finally:
            await api.close()
    error = info.value
    assert isinstance(error, HttpTimeout)
    assert isinstance(error, HttpError)  # `except HttpError` still catches it
    assert (error.endpoint, error.status) == ("/system/info", None)
    assert "no answer within 0.3 s" in str(error)
    assert "request_timeout" in str(error)


async def test_a_websocket_that_never_opens_is_a_timeout_within_connect_timeout() -> None:
    async with silent_server("/galileo/status") as port:
        url = f"http://127.0.0.1:{port}?ws_port={port}"
        started = time.monotonic()
        with pytest.raises(HttpTimeout, match=r"within 0\.3 s \(connect_timeout\)") as info:
            await galileo.connect(url, reconnect=False, connect_timeout=0.3)
        assert time.monotonic() - started < 3.0  # not the 5 s request_timeout
    assert info.value.endpoint == "/galileo/status"


async def test_a_wrong_password_is_an_authentication_error() -> None:
    async with Simulator() as sim:
        face = await sim.serve_http(token_check=True)
        port, ws_port = face.address[1], face.ws_address[1]
        url = f"http://admin:wrong@127.0.0.1:{port}?ws_port={ws_port}"
        with pytest.raises(AuthenticationError, match="wrong username or password") as info:
            await galileo.connect(url, reconnect=False)
        assert info.value.endpoint == "/token"
        assert "wrong" not in str(info.value).replace("wrong username", "")


async def test_no_token_or_a_refused_token_is_an_authentication_error() -> None:
    async with Simulator() as sim:
        face = await sim.serve_http(token_check=True)
        port, ws_port = face.address[1], face.ws_address[1]
        url = f"http://127.0.0.1:{port}?ws_port={ws_port}"
        with pytest.raises(AuthenticationError, match="give token= or username") as info:
            await galileo.connect(url, reconnect=False)
        assert (info.value.status, info.value.endpoint) == (401, "/galileo/status")
        with pytest.raises(AuthenticationError, match="refused the token") as info:
            await galileo.connect(url, reconnect=False, token="n0t-a-t0ken")
        assert info.value.status == 401
        assert "n0t-a-t0ken" not in str(info.value)
        face.tokens.add("t0ken")
        async with galileo.connect(url, token="t0ken") as robot:
            face.tokens.clear()  # revoked: a REST call is refused
            with pytest.raises(AuthenticationError, match="refused the token") as info:
                await http_of(robot).maps()
            assert (info.value.status, info.value.endpoint) == (401, "/map/image")


async def test_a_refused_connection_says_the_cause_and_the_port_it_tried() -> None:
    port, ws_port = free_port(), free_port()
    with pytest.raises(HttpError) as info:
        await galileo.connect(f"http://127.0.0.1:{port}?ws_port={ws_port}", reconnect=False)
    message = str(info.value)
    assert f"cannot connect to 127.0.0.1:{ws_port} (Connection refused)" in message
    assert "ClientConnectorError" not in message
    assert "ws_port (3547" not in message  # given: no note about the default
    with pytest.raises(HttpError) as info:
        await galileo.connect(f"http://admin:pw@127.0.0.1:{port}", reconnect=False)
    message = str(info.value)
    assert message == f"GET /api/v1/token: cannot connect to 127.0.0.1:{port} (Connection refused)"


async def test_the_default_websocket_port_is_named_when_it_is_not_the_apis() -> None:
    port = free_port()
    with pytest.raises(HttpError) as info:
        await galileo.connect(f"http://127.0.0.1:{port}", reconnect=False)
    message = str(info.value)
    assert "ws://127.0.0.1:3547/galileo/status" in message
    assert f"not on the API's port {port}: give ws_port=" in message
