"""HttpChannel: status from the WebSocket /galileo/status, commands as REST calls."""

from __future__ import annotations

import asyncio
import json
import logging
from typing import Any

import aiohttp

from ..errors import (
    AuthenticationError,
    ConnectionLost,
    GalileoConnectionError,
    HttpError,
    HttpTimeout,
    InvalidArgument,
)
from ..protocol import ApiCall, Command, DecoderStats
from ..transports.channel import Capabilities, Channel, Feed
from ..transports.connectors import DEFAULT_CONNECT_TIMEOUT
from ..transports.stats import clock_note, clocks
from .calls import rest_call
from .client import HttpApi, failure_text, tls_context
from .options import (
    DEFAULT_HTTP_PORT,
    DEFAULT_PING_INTERVAL,
    DEFAULT_REQUEST_TIMEOUT,
    DEFAULT_WS_PORT,
    HttpAddress,
    redact_http_url,
)
from .status import status_from_json

__all__ = ["STATUS_TOPIC", "HttpChannel"]

_log = logging.getLogger(__name__)

#: The WebSocket path of the status topic (http.md, "Websocket相关API").
STATUS_TOPIC = "/galileo/status"


def _read(command: Command) -> bool:
    """A call that only reads a task (GET /task): pause and resume keep to the one started."""
    return isinstance(command, ApiCall) and command.method == "GET" and command.endpoint == "/task"


class HttpChannel(Channel):
    """The vendor's HTTP API (REST on 3546) and WebSocket status (3547) as one channel.

    ``write`` makes the command's REST call (calls.REST_CALLS) and returns its JSON answer,
    so the Link's send returns it and raises its HttpError. A Velocity is PUT /system/speed.
    """

    capabilities = Capabilities(velocity=True, pose_goals=True, rest_api=True)

    def __init__(
        self,
        address: HttpAddress,
        *,
        request_timeout: float = DEFAULT_REQUEST_TIMEOUT,
        ping_interval: float = DEFAULT_PING_INTERVAL,
        connect_timeout: float = DEFAULT_CONNECT_TIMEOUT,
        name: str | None = None,
    ) -> None:
        self.address = address
        self.name = redact_http_url(name or address.base_url)
        self.api = HttpApi(
            address.base_url,
            username=address.username,
            password=address.password,
            token=address.token,
            timeout=request_timeout,
            ssl_context=tls_context(address),
        )
        self.ping_interval = ping_interval
        self.connect_timeout = connect_timeout
        #: The id of the last task a call returned: pause and resume act on it.
        self.task_id: str | None = None
        #: REST calls of written commands that failed since the channel was made.
        self.failed_calls = 0
        self._decoder_stats = DecoderStats()
        self._feed: Feed | None = None
        self._ws: aiohttp.ClientWebSocketResponse[bool] | None = None
        self._abandoned: aiohttp.ClientWebSocketResponse[bool] | None = None
        self._tasks: list[asyncio.Task[None]] = []

    def __repr__(self) -> str:
        return f"<HttpChannel {self.name}>"

    @property
    def decoder_stats(self) -> DecoderStats:
        """Counted by the link per status; undecodable messages' bytes in bytes_discarded."""
        return self._decoder_stats

    def ws_url(self, topic: str = STATUS_TOPIC) -> str:
        """The WebSocket URL of ``topic`` (without the token)."""
        scheme = "wss" if self.address.secure else "ws"
        return f"{scheme}://{self.address.host}:{self.address.ws_port}{topic}"

    async def call(
        self,
        method: str,
        endpoint: str,
        params: dict[str, Any] | None = None,
        body: dict[str, Any] | None = None,
    ) -> Any:
        """One REST call outside the command queue (HttpApi.call): the Robot's HTTP reads."""
        return await self.api.call(method, endpoint, params, body)

    # --- the Channel ---------------------------------------------------------------------

    async def open(self, feed: Feed) -> None:
        """Log in, open the status WebSocket and report its statuses to ``feed``."""
        await self._drop()
        self._feed = feed
        await self.api.login()
        what = f"cannot open the WebSocket {self.ws_url()} of {self.name}"
        began = clocks()
        try:
            ws = await asyncio.wait_for(
                self.api.session.ws_connect(
                    self.ws_url(),
                    params=self.api.token_query(),
                    timeout=aiohttp.ClientWSTimeout(ws_close=self.connect_timeout),
                    autoping=True,
                    heartbeat=None,  # re-armed by every frame, it never fires: our timer pings
                ),
                self.connect_timeout,
            )
        except asyncio.TimeoutError:
            raise HttpTimeout(
                f"{what}: no answer within {self.connect_timeout} s (connect_timeout)"
                f"{clock_note(began)}{self._ws_port_hint()}",
                endpoint=STATUS_TOPIC,
            ) from None
        except aiohttp.WSServerHandshakeError as exc:
            if exc.status == 401:
                raise AuthenticationError(
                    f"{what}: HTTP 401{self.api.refused_hint()}", endpoint=STATUS_TOPIC, status=401
                ) from None
            raise HttpError(
                f"{what}: HTTP {exc.status}{self._ws_port_hint()}",
                endpoint=STATUS_TOPIC,
                status=exc.status,
            ) from None
        except (aiohttp.ClientError, OSError) as exc:
            raise HttpError(
                f"{what}: {failure_text(exc)}{self._ws_port_hint()}",
                endpoint=STATUS_TOPIC,
                status=None,
            ) from None
        self._ws = ws
        self._tasks = [
            asyncio.create_task(self._read(ws, feed), name=f"{self!r} reader"),
            asyncio.create_task(self._ping(ws), name=f"{self!r} pinger"),
        ]

    def accepts(self, command: Command) -> None:
        """NotSupported for a command without an HTTP API form (nothing is queued)."""
        rest_call(command)

    async def write(self, command: Command) -> Any:
        """Make ``command``'s REST call; its JSON answer, or its HttpError (counted)."""
        if self._ws is None or self._ws.closed:
            raise ConnectionLost(f"not connected to {self.name}")
        try:
            answer = await rest_call(command)(command, self.api, self.task_id)
        except GalileoConnectionError as exc:
            self.failed_calls += 1
            _log.warning("%s: %s", self.name, exc)
            raise
        if isinstance(answer, dict) and isinstance(answer.get("id"), str) and not _read(command):
            self.task_id = answer["id"]
        return answer

    def abandon(self, reason: str) -> None:
        """Stop reporting the WebSocket; the next open (or close) closes it."""
        self._abandoned, self._ws = self._ws, None

    async def close(self) -> None:
        """Close the WebSocket, its tasks and the REST session."""
        try:
            await self._drop()
        finally:
            await self.api.close()

    # --- internals -----------------------------------------------------------------------

    def _ws_port_hint(self) -> str:
        """Say the WebSocket has a port of its own, when it defaulted away from the API's."""
        address = self.address
        api_port = address.base_url.rpartition(":")[2]
        if address.ws_port != DEFAULT_WS_PORT or api_port == str(DEFAULT_HTTP_PORT):
            return ""
        return (
            f"; the status WebSocket listens on ws_port ({DEFAULT_WS_PORT} unless given), "
            f"not on the API's port {api_port}: give ws_port= (or ?ws_port= in the URL)"
        )

    async def _read(self, ws: aiohttp.ClientWebSocketResponse[bool], feed: Feed) -> None:
        stats = feed.stats
        error: BaseException | None = None
        try:
            async for message in ws:
                if message.type is not aiohttp.WSMsgType.TEXT:
                    continue
                stats.bytes_received += len(message.data)
                try:
                    status = status_from_json(json.loads(message.data))
                except (ValueError, InvalidArgument):
                    self._decoder_stats.bytes_discarded += len(message.data)
                    continue
                feed.status(status)
            error = ws.exception()
        except (aiohttp.ClientError, OSError) as exc:
            error = exc
        if self._ws is ws:
            feed.lost(error or ConnectionLost("the WebSocket closed"))

    async def _ping(self, ws: aiohttp.ClientWebSocketResponse[bool]) -> None:
        while not ws.closed:
            await asyncio.sleep(self.ping_interval)
            try:
                await ws.ping()
            except (aiohttp.ClientError, ConnectionError, RuntimeError):
                return  # the reader sees the close

    async def _drop(self) -> None:
        """Cancel the reader and pinger and close the WebSockets (current and abandoned)."""
        tasks, self._tasks = self._tasks, []
        for task in tasks:
            task.cancel()
        for ws in (self._ws, self._abandoned):
            if ws is not None:
                await ws.close()
        self._ws = self._abandoned = None
        if tasks:
            await asyncio.wait(tasks)
