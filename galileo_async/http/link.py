"""HttpLink: status from the WebSocket /galileo/status, commands through the REST API."""

from __future__ import annotations

import asyncio
import json
import logging
from collections import deque
from collections.abc import Awaitable, Callable
from typing import Any

import aiohttp

from ..errors import (
    AuthenticationError,
    ConnectionLost,
    GalileoConnectionError,
    HttpError,
    HttpTimeout,
    InvalidArgument,
    NotSupported,
)
from ..protocol import commands as cmd
from ..protocol.api_call import ApiCall
from ..protocol.velocity import PoseGoal, Velocity
from ..transports.base import BaseLink
from ..transports.connectors import DEFAULT_CONNECT_TIMEOUT
from ..transports.stats import StatusSink
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

__all__ = ["STATUS_TOPIC", "HttpLink"]

_log = logging.getLogger(__name__)

#: The WebSocket path of the status topic (http.md, "Websocket相关API").
STATUS_TOPIC = "/galileo/status"
#: The REST call of each command without parameters: (method, endpoint).
_FIXED: dict[type[cmd.Command], tuple[str, str]] = {
    cmd.Cancel: ("GET", "/navigation/stop_nav_task"),
    cmd.StopNavigation: ("GET", "/navigation/stop"),
    cmd.StopPatrol: ("DELETE", "/navigation/loop_task"),
    cmd.StartCharging: ("GET", "/navigation/go_charge"),
    cmd.StopCharging: ("GET", "/navigation/stop_charge"),
    cmd.ShutdownHost: ("GET", "/system/shutdown"),
    cmd.StartMapping: ("GET", "/map/start"),
    cmd.StopMapping: ("GET", "/map/stop"),
}
_Call = Callable[[], Awaitable[Any]]


class HttpLink(BaseLink):
    """The vendor's HTTP API (REST on 3546) and WebSocket status (3547) as one link.

    Each command becomes its REST call, made in order by one worker; send() returns the
    call's answer and raises its HttpError if it failed (a command queued without a sender
    waiting, e.g. a cancel on exit, is logged instead). An ApiCall is that call as is; a
    Velocity is PUT /system/speed.
    """

    carries_velocity = True
    carries_pose_goals = True
    carries_api_calls = True

    def __init__(
        self,
        store: StatusSink,
        address: HttpAddress,
        *,
        request_timeout: float = DEFAULT_REQUEST_TIMEOUT,
        ping_interval: float = DEFAULT_PING_INTERVAL,
        connect_timeout: float = DEFAULT_CONNECT_TIMEOUT,
        name: str | None = None,
        **base_options: Any,
    ) -> None:
        super().__init__(store, **base_options)
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
        #: REST calls that failed since the link opened.
        self.failed_calls = 0
        self._ws: aiohttp.ClientWebSocketResponse[bool] | None = None
        self._abandoned: aiohttp.ClientWebSocketResponse[bool] | None = None
        self._tasks: list[asyncio.Task[None]] = []
        #: Calls still to make, in order: (sets the speed, call, its answer).
        self._calls: deque[tuple[bool, _Call, asyncio.Future[Any]]] = deque()
        self._calls_ready = asyncio.Event()
        #: The answer of each written command's call, by the command's id(), until send() takes it.
        self._answers: dict[int, asyncio.Future[Any]] = {}

    def __repr__(self) -> str:
        return f"<HttpLink {self.name}>"

    def ws_url(self, topic: str = STATUS_TOPIC) -> str:
        """The WebSocket URL of ``topic`` (without the token)."""
        scheme = "wss" if self.address.secure else "ws"
        return f"{scheme}://{self.address.host}:{self.address.ws_port}{topic}"

    async def _connect(self) -> None:
        await self._drop()
        await self.api.login()
        what = f"cannot open the WebSocket {self.ws_url()} of {self.name}"
        try:
            self._ws = await asyncio.wait_for(
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
                f"{self._ws_port_hint()}",
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
        ws = self._ws
        assert ws is not None
        self._tasks = [
            asyncio.create_task(self._read(ws), name=f"{self!r} reader"),
            asyncio.create_task(self._ping(ws), name=f"{self!r} pinger"),
            asyncio.create_task(self._call_worker(), name=f"{self!r} calls"),
        ]

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

    async def _read(self, ws: aiohttp.ClientWebSocketResponse[bool]) -> None:
        error: BaseException | None = None
        try:
            async for message in ws:
                if message.type is not aiohttp.WSMsgType.TEXT:
                    continue
                self.stats.bytes_received += len(message.data)
                try:
                    status = status_from_json(json.loads(message.data))
                except (ValueError, InvalidArgument):
                    self.stats.decoder.bytes_discarded += len(message.data)
                    continue
                self._on_status(status)
            error = ws.exception()
        except (aiohttp.ClientError, OSError) as exc:
            error = exc
        if self._ws is ws:
            self._on_lost(error or ConnectionLost("the WebSocket closed"))

    async def _ping(self, ws: aiohttp.ClientWebSocketResponse[bool]) -> None:
        while not ws.closed:
            await asyncio.sleep(self.ping_interval)
            try:
                await ws.ping()
            except (aiohttp.ClientError, ConnectionError, RuntimeError):
                return  # the reader sees the close

    def enqueue(
        self,
        command: cmd.Command,
        *,
        superseded_by: tuple[type[cmd.Command], ...] = (),
        written: asyncio.Future[bool] | None = None,
    ) -> asyncio.Future[bool]:
        """As BaseLink's; NotSupported, nothing queued, for a command without an HTTP form."""
        self._call_of(command)
        return super().enqueue(command, superseded_by=superseded_by, written=written)

    async def send(
        self, command: cmd.Command, *, written: asyncio.Future[bool] | None = None
    ) -> Any:
        """Queue ``command``; once its REST call answered, the answer (HttpError if it failed)."""
        await super().send(command, written=written)
        answer = self._answers.pop(id(command), None)
        if answer is None:
            return None  # dropped before its write: no call was made
        return await asyncio.shield(answer)  # a cancelled sender leaves the call to finish

    async def _call_worker(self) -> None:
        calls = self._calls
        while True:
            if not calls:
                self._calls_ready.clear()
                await self._calls_ready.wait()
                continue
            speed, call, answer = calls.popleft()
            if speed and calls and calls[0][0]:
                # A newer speed is queued behind: on a slow server speeds must not pile up
                # (a stop behind them would wait), so only the newest is put.
                answer.set_result(None)
                continue
            try:
                result = await call()
            except asyncio.CancelledError:  # the connection dropped or the link closes
                if not answer.done():
                    answer.set_exception(ConnectionLost(f"{self.name}: the call was cut off"))
                raise
            except GalileoConnectionError as exc:
                self.failed_calls += 1
                _log.warning("%s: %s", self.name, exc)
                if not answer.done():
                    answer.set_exception(exc)
                continue
            if isinstance(result, dict) and isinstance(result.get("id"), str):
                self.task_id = result["id"]
            if not answer.done():
                answer.set_result(result)

    def _write(self, command: cmd.Command) -> None:
        if self._ws is None or self._ws.closed:
            raise ConnectionLost(f"not connected to {self.name}")
        call = self._call_of(command)
        answer: asyncio.Future[Any] = asyncio.get_running_loop().create_future()
        answer.add_done_callback(self._settled(id(command)))
        self._answers[id(command)] = answer
        self._calls.append((isinstance(command, (Velocity, cmd.Stop)), call, answer))
        self._calls_ready.set()

    def _settled(self, key: int) -> Callable[[asyncio.Future[Any]], None]:
        def settled(answer: asyncio.Future[Any]) -> None:
            if not answer.cancelled():
                answer.exception()  # retrieved: a failure nobody awaits is only logged
            if self._answers.get(key) is answer:
                # Normally send() took it first; a command queued by enqueue() has no sender.
                self._answers.pop(key)

        return settled

    def _call_of(self, command: cmd.Command) -> _Call:
        """The REST call that carries ``command`` (not made yet); NotSupported if none does."""
        api = self.api
        fixed = _FIXED.get(type(command))
        if fixed is not None:
            return lambda: api.call(*fixed)
        if isinstance(command, ApiCall):
            params = None if command.params is None else dict(command.params)
            body = None if command.body is None else dict(command.body)
            return lambda: api.call(command.method, command.endpoint, params, body)
        if isinstance(command, PoseGoal):
            body = {"x": command.x, "y": command.y, "theta": command.theta}
            return lambda: api.call("POST", "/navigation/start_nav_task", body=body)
        if isinstance(command, cmd.Goto):
            return lambda: api.call(
                "GET", "/navigation/move_to_index", {"index": command.target_id}
            )
        if isinstance(command, (Velocity, cmd.Stop)):
            linear, angular = (
                (command.linear, command.angular) if isinstance(command, Velocity) else (0.0, 0.0)
            )
            body = {"speed_x": linear, "speed_y": 0.0, "speed_angle": angular}
            return lambda: api.call("PUT", "/system/speed", body=body)
        if isinstance(command, (cmd.Pause, cmd.Resume)):
            verb = "pause" if isinstance(command, cmd.Pause) else "resume"
            return lambda: self._task_call(verb)
        if isinstance(command, cmd.StartNavigation):
            return self._start_navigation
        raise NotSupported(
            f"{command} has no HTTP API form: use a serial, socket://, udp:// or ros:// link"
        )

    async def _task_call(self, verb: str) -> Any:
        task_id = self.task_id
        if task_id is None:  # a task someone else started: the one that works
            tasks = await self.api.call("GET", "/task")
            working = [t for t in tasks if isinstance(t, dict) and t.get("state") == "WORKING"]
            if not working:
                return None
            task_id = str(working[0].get("id"))
        return await self.api.call("GET", f"/task/{verb}", {"id": task_id})

    async def _start_navigation(self) -> Any:
        current = await self.api.call("GET", "/navigation/current_path")
        where = current if isinstance(current, dict) else {}
        return await self.api.call(
            "GET", "/navigation/start", {"map": where.get("map", ""), "path": where.get("path", "")}
        )

    def _abandon(self, reason: str) -> None:
        # Its reader no longer reports it; the reconnect's _drop closes it.
        self._abandoned, self._ws = self._ws, None
        self._on_lost(ConnectionLost(reason))

    async def _drop(self) -> None:
        tasks, self._tasks = self._tasks, []
        for task in tasks:
            task.cancel()
        while self._calls:  # calls of a lost connection are not made after it
            answer = self._calls.popleft()[2]
            answer.set_exception(ConnectionLost(f"not sent: the connection to {self.name} dropped"))
        for ws in (self._ws, self._abandoned):
            if ws is not None:
                await ws.close()
        self._ws = self._abandoned = None
        if tasks:
            await asyncio.wait(tasks)

    async def _disconnect(self) -> None:
        try:
            await self._drop()
        finally:
            await self.api.close()
