"""Foxglove peers: a plain WebSocket client (aiohttp) decoding the ws-protocol by hand, and
the npm client @foxglove/ws-protocol in tests/peers/foxglove (node)."""

from __future__ import annotations

import asyncio
import contextlib
import json
import shutil
import struct
from collections.abc import AsyncIterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import aiohttp

from tests.support.peers import missing_peer

__all__ = [
    "PEER_DIR", "WAIT", "FoxgloveClient", "ServiceFailed", "connected", "require_node_peer",
]  # fmt: skip

#: Real seconds any wait of these tests may take.
WAIT = 20.0
#: The npm client's folder (package.json, package-lock.json, client.cjs).
PEER_DIR = Path(__file__).resolve().parents[1] / "peers" / "foxglove"

# Binary opcodes of the ws-protocol (https://github.com/foxglove/ws-protocol/blob/main/docs/spec.md).
MESSAGE_DATA = 0x01
SERVICE_CALL_RESPONSE = 0x03
SERVICE_CALL_REQUEST = 0x02


def require_node_peer() -> str:
    """The node executable, with the peer's packages installed; skip or fail as peers do."""
    node = shutil.which("node")
    if node is None:
        missing_peer("Node.js")
    if not (PEER_DIR / "node_modules" / "@foxglove" / "ws-protocol").is_dir():
        missing_peer("@foxglove/ws-protocol (npm ci --prefix tests/peers/foxglove)")
    assert node is not None
    return node


class ServiceFailed(Exception):
    """The server answered a service call with serviceCallFailure (the message)."""


@dataclass
class FoxgloveClient:
    """A hand-decoding ws-protocol client over one aiohttp WebSocket."""

    ws: aiohttp.ClientWebSocketResponse
    server_info: dict[str, Any] = field(default_factory=dict)
    channels: dict[str, dict[str, Any]] = field(default_factory=dict)
    services: dict[str, dict[str, Any]] = field(default_factory=dict)
    subscriptions: dict[int, str] = field(default_factory=dict)
    messages: dict[str, list[bytes]] = field(default_factory=dict)
    answers: dict[int, tuple[bool, bytes | str]] = field(default_factory=dict)
    _next_call: int = 1

    async def read_one(self) -> None:
        """Read and file one message from the server."""
        message = await self.ws.receive(timeout=WAIT)
        if message.type == aiohttp.WSMsgType.TEXT:
            data = json.loads(message.data)
            op = data["op"]
            if op == "serverInfo":
                self.server_info = data
            elif op == "advertise":
                self.channels.update({c["topic"]: c for c in data["channels"]})
            elif op == "advertiseServices":
                self.services.update({s["name"]: s for s in data["services"]})
            elif op == "serviceCallFailure":
                self.answers[data["callId"]] = (False, data["message"])
            return
        assert message.type == aiohttp.WSMsgType.BINARY, message
        raw: bytes = message.data
        if raw[0] == MESSAGE_DATA:
            subscription, _log_time = struct.unpack_from("<IQ", raw, 1)
            topic = self.subscriptions[subscription]
            self.messages.setdefault(topic, []).append(raw[13:])
        elif raw[0] == SERVICE_CALL_RESPONSE:
            _service, call, size = struct.unpack_from("<III", raw, 1)
            self.answers[call] = (True, raw[13 + size :])

    async def until(self, done: Any) -> None:
        """Read until ``done()`` holds (within WAIT seconds)."""
        async with asyncio.timeout(WAIT):
            while not done():
                await self.read_one()

    async def subscribe(self, *topics: str) -> None:
        """Subscribe to ``topics`` (advertised already, else waited for)."""
        await self.until(lambda: all(topic in self.channels for topic in topics))
        wanted = []
        for topic in topics:
            number = len(self.subscriptions) + 1
            self.subscriptions[number] = topic
            wanted.append({"id": number, "channelId": self.channels[topic]["id"]})
        await self.ws.send_str(json.dumps({"op": "subscribe", "subscriptions": wanted}))

    async def next_message(self, topic: str) -> bytes:
        """The next message on ``topic`` (one already received first)."""
        await self.until(lambda: self.messages.get(topic))
        return self.messages[topic].pop(0)

    async def call(self, service: str, request: bytes | dict[str, Any]) -> Any:
        """Call ``service``; its JSON answer, or ServiceFailed with the server's message."""
        await self.until(lambda: service in self.services)
        payload = request if isinstance(request, bytes) else json.dumps(request).encode()
        call, self._next_call = self._next_call, self._next_call + 1
        head = struct.pack("<BIII", SERVICE_CALL_REQUEST, self.services[service]["id"], call, 4)
        await self.ws.send_bytes(head + b"json" + payload)
        await self.until(lambda: call in self.answers)
        ok, answer = self.answers.pop(call)
        if not ok:
            raise ServiceFailed(answer)
        assert isinstance(answer, bytes)
        return json.loads(answer)


@contextlib.asynccontextmanager
async def connected(url: str, protocol: str = "foxglove.sdk.v1") -> AsyncIterator[FoxgloveClient]:
    """A FoxgloveClient on ``url`` asking for ``protocol``, its server info read."""
    async with (
        aiohttp.ClientSession() as session,
        session.ws_connect(
            url, protocols=[protocol], timeout=aiohttp.ClientWSTimeout(ws_close=WAIT)
        ) as ws,
    ):
        client = FoxgloveClient(ws)
        await client.until(lambda: client.server_info)
        yield client
