"""ROS 1 master and slave XML-RPC APIs over asyncio (no blocking call on the event loop)."""

from __future__ import annotations

import asyncio
import os
import xmlrpc.client
from collections.abc import Callable
from typing import Any
from urllib.parse import urlsplit

from ..errors import GalileoConnectionError
from ._server import close_server

__all__ = [
    "MAX_HTTP_BODY",
    "MasterClient",
    "RosApiError",
    "SlaveServer",
    "http_uri",
    "request_topic",
    "xmlrpc_call",
]

#: Largest XML-RPC request or response accepted.
MAX_HTTP_BODY = 1 << 20
_MAX_HTTP_HEAD = 16 * 1024


class RosApiError(GalileoConnectionError):
    """An XML-RPC peer could not be reached, answered badly, or returned a failure code."""


def http_uri(host: str, port: int) -> str:
    """``http://host:port/`` with an IPv6 literal in brackets."""
    return f"http://[{host}]:{port}/" if ":" in host else f"http://{host}:{port}/"


def _split_uri(uri: str) -> tuple[str, int, str]:
    parts = urlsplit(uri)
    if parts.scheme != "http" or not parts.hostname:
        raise RosApiError(f"not an http XML-RPC URI: {uri!r}")
    return parts.hostname, parts.port or 80, parts.path or "/"


async def _read_http(reader: asyncio.StreamReader) -> tuple[str, dict[str, str], bytes]:
    """Read one HTTP message: first line, lower-cased headers, body (by Content-Length)."""
    head = await reader.readuntil(b"\r\n\r\n")
    if len(head) > _MAX_HTTP_HEAD:
        raise RosApiError("HTTP head too large")
    lines = head.decode("latin-1").split("\r\n")
    headers: dict[str, str] = {}
    for line in lines[1:]:
        key, sep, value = line.partition(":")
        if sep:
            headers[key.strip().lower()] = value.strip()
    length = headers.get("content-length")
    if length is None:
        body = await reader.read(MAX_HTTP_BODY + 1)
    else:
        if not length.isdigit() or int(length) > MAX_HTTP_BODY:
            raise RosApiError(f"bad Content-Length {length!r}")
        body = await reader.readexactly(int(length))
    if len(body) > MAX_HTTP_BODY:
        raise RosApiError("HTTP body too large")
    return lines[0], headers, body


async def xmlrpc_call(uri: str, method: str, *params: Any, timeout: float) -> Any:
    """Call an XML-RPC method over a fresh connection; raise RosApiError on any failure."""
    host, port, path = _split_uri(uri)
    body = xmlrpc.client.dumps(params, method, allow_none=False).encode()
    request = (
        f"POST {path} HTTP/1.1\r\nHost: {host}:{port}\r\nContent-Type: text/xml\r\n"
        f"Content-Length: {len(body)}\r\nConnection: close\r\n\r\n"
    ).encode() + body

    async def exchange() -> bytes:
        reader, writer = await asyncio.open_connection(host, port)
        try:
            writer.write(request)
            status_line, _, reply = await _read_http(reader)
        finally:
            writer.close()
        if " 200 " not in f"{status_line} ":
            raise RosApiError(f"{method} at {uri}: HTTP {status_line!r}")
        return reply

    try:
        reply = await asyncio.wait_for(exchange(), timeout)
        (result,), _ = xmlrpc.client.loads(reply)
    except RosApiError:
        raise
    except asyncio.TimeoutError:
        raise RosApiError(f"{method} at {uri}: no reply within {timeout} s (rpc_timeout)") from None
    except (OSError, asyncio.IncompleteReadError) as exc:
        raise RosApiError(f"{method} at {uri} failed: {exc!r}") from exc
    except (xmlrpc.client.Fault, xmlrpc.client.ResponseError, ValueError) as exc:
        raise RosApiError(f"{method} at {uri}: bad reply: {exc!r}") from exc
    return result


def _value(method: str, result: Any) -> Any:
    """Unpack a ROS API (code, statusMessage, value) triple; code 1 is success."""
    if not isinstance(result, (list, tuple)) or len(result) != 3:
        raise RosApiError(f"{method}: not a ROS API reply: {result!r}")
    code, message, value = result
    if code != 1:
        raise RosApiError(f"{method} failed (code {code}): {message}")
    return value


class MasterClient:
    """The ROS master API calls a node needs, each bounded by ``timeout``."""

    def __init__(self, master_uri: str, caller_id: str, *, timeout: float = 2.0) -> None:
        _split_uri(master_uri)
        self.master_uri = master_uri
        self.caller_id = caller_id
        self.timeout = timeout

    async def _call(self, method: str, *params: Any) -> Any:
        result = await xmlrpc_call(
            self.master_uri, method, self.caller_id, *params, timeout=self.timeout
        )
        return _value(method, result)

    async def register_publisher(self, topic: str, msg_type: str, caller_api: str) -> list[str]:
        """Advertise a topic; return the current subscribers' slave URIs."""
        return list(await self._call("registerPublisher", topic, msg_type, caller_api))

    async def register_subscriber(self, topic: str, msg_type: str, caller_api: str) -> list[str]:
        """Subscribe to a topic; return the current publishers' slave URIs."""
        return list(await self._call("registerSubscriber", topic, msg_type, caller_api))

    async def unregister_publisher(self, topic: str, caller_api: str) -> None:
        """Withdraw an advertisement."""
        await self._call("unregisterPublisher", topic, caller_api)

    async def unregister_subscriber(self, topic: str, caller_api: str) -> None:
        """Withdraw a subscription."""
        await self._call("unregisterSubscriber", topic, caller_api)

    async def get_param(self, key: str) -> Any:
        """A parameter's value; None when the parameter server does not have it."""
        result = await xmlrpc_call(
            self.master_uri, "getParam", self.caller_id, key, timeout=self.timeout
        )
        if isinstance(result, (list, tuple)) and len(result) == 3 and result[0] == -1:
            return None  # rosmaster: "Parameter [key] is not set"
        return _value("getParam", result)

    async def get_pid(self) -> int:
        """The master's process id (changes when the master restarts)."""
        return int(await self._call("getPid"))


async def request_topic(
    slave_uri: str, caller_id: str, topic: str, *, timeout: float
) -> tuple[str, int]:
    """Ask a publisher's slave API where to connect for TCPROS: (host, port)."""
    result = await xmlrpc_call(
        slave_uri, "requestTopic", caller_id, topic, [["TCPROS"]], timeout=timeout
    )
    value = _value("requestTopic", result)
    if not isinstance(value, (list, tuple)) or len(value) != 3 or value[0] != "TCPROS":
        raise RosApiError(f"requestTopic at {slave_uri}: no TCPROS endpoint: {value!r}")
    return str(value[1]), int(value[2])


Handler = Callable[..., Any]


class _HttpConnection(asyncio.Protocol):
    """One XML-RPC request: buffer it, dispatch synchronously, answer, close."""

    def __init__(self, server: SlaveServer) -> None:
        self._server = server
        self._buffer = bytearray()
        self._transport: asyncio.Transport | None = None

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        assert isinstance(transport, asyncio.Transport)
        self._transport = transport

    def data_received(self, data: bytes) -> None:
        assert self._transport is not None
        self._buffer += data
        end = self._buffer.find(b"\r\n\r\n")
        if end < 0:
            if len(self._buffer) > _MAX_HTTP_HEAD:
                self._transport.abort()
            return
        length = 0
        for line in bytes(self._buffer[:end]).decode("latin-1").split("\r\n")[1:]:
            key, _, value = line.partition(":")
            if key.strip().lower() == "content-length" and value.strip().isdigit():
                length = int(value.strip())
        if length > MAX_HTTP_BODY:
            self._transport.abort()
            return
        if len(self._buffer) < end + 4 + length:
            return
        body = bytes(self._buffer[end + 4 : end + 4 + length])
        self._buffer.clear()
        reply = self._server.dispatch(body)
        self._transport.write(
            (
                "HTTP/1.1 200 OK\r\nContent-Type: text/xml\r\n"
                f"Content-Length: {len(reply)}\r\nConnection: close\r\n\r\n"
            ).encode()
            + reply
        )
        self._transport.close()


class SlaveServer:
    """A node's slave API: requestTopic, publisherUpdate and the introspection calls."""

    def __init__(self, caller_id: str, master_uri: str) -> None:
        self.caller_id = caller_id
        self.master_uri = master_uri
        self.uri: str | None = None
        #: topic → (type, (host, port) of our TCPROS publisher for that topic).
        self.publications: dict[str, tuple[str, tuple[str, int]]] = {}
        #: topic → (type, callback(publisher URIs)) for our subscriptions.
        self.subscriptions: dict[str, tuple[str, Callable[[list[str]], None]]] = {}
        self._server: asyncio.Server | None = None

    async def start(self, host: str, port: int = 0) -> str:
        """Listen on host:port; return the slave URI to give the master."""
        loop = asyncio.get_running_loop()
        try:
            self._server = await loop.create_server(lambda: _HttpConnection(self), host, port)
        except OSError as exc:
            raise RosApiError(f"cannot listen on {host}:{port}: {exc}") from exc
        bound = self._server.sockets[0].getsockname()[1]
        self.uri = http_uri(host, bound)
        return self.uri

    def stop(self) -> None:
        """Stop listening, at once (close() also waits)."""
        if self._server is not None:
            self._server.close()

    async def close(self) -> None:
        """Stop listening and wait (bounded) for the server to close."""
        self.stop()
        server, self._server = self._server, None
        await close_server(server)

    def dispatch(self, body: bytes) -> bytes:
        """Answer one XML-RPC request body (never raises)."""
        try:
            params, method = xmlrpc.client.loads(body)
            handler: Handler | None = getattr(self, f"_rpc_{method}", None)
            if handler is None:
                result: Any = [-1, f"unknown method {method}", 0]
            else:
                result = handler(*params[1:])
        except Exception as exc:  # a malformed call is answered, never raised into the loop
            result = [-1, f"error: {exc!r}", 0]
        return xmlrpc.client.dumps((result,), methodresponse=True, allow_none=False).encode()

    def _rpc_requestTopic(self, topic: str, protocols: list[Any]) -> list[Any]:
        if topic not in self.publications:
            return [-1, f"not a publisher of {topic}", []]
        if not any(p and p[0] == "TCPROS" for p in protocols):
            return [0, "no supported protocol (only TCPROS)", []]
        _, (host, port) = self.publications[topic]
        return [1, f"ready on {host}:{port}", ["TCPROS", host, port]]

    def _rpc_publisherUpdate(self, topic: str, publishers: list[str]) -> list[Any]:
        if topic in self.subscriptions:
            self.subscriptions[topic][1](list(publishers))
        return [1, "", 0]

    def _rpc_getBusStats(self) -> list[Any]:
        return [1, "", [[], [], []]]

    def _rpc_getBusInfo(self) -> list[Any]:
        return [1, "", []]

    def _rpc_getMasterUri(self) -> list[Any]:
        return [1, "", self.master_uri]

    def _rpc_getPid(self) -> list[Any]:
        return [1, "", os.getpid()]

    def _rpc_getSubscriptions(self) -> list[Any]:
        return [1, "", [[topic, kind] for topic, (kind, _) in self.subscriptions.items()]]

    def _rpc_getPublications(self) -> list[Any]:
        return [1, "", [[topic, kind] for topic, (kind, _) in self.publications.items()]]

    def _rpc_paramUpdate(self, key: str, value: Any) -> list[Any]:
        return [1, "", 0]

    def _rpc_shutdown(self, message: str = "") -> list[Any]:
        return [1, "", 0]
