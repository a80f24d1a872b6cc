"""Helpers for the VDA 5050 tests: a real Mosquitto broker and a master control client."""

from __future__ import annotations

import asyncio
import contextlib
import getpass
import itertools
import json
import os
import shutil
import subprocess
from collections.abc import AsyncIterator, Callable
from pathlib import Path
from typing import Any

import aiomqtt
import anyio
import jsonschema
import pytest
from peers import missing_peer
from ros_support import free_port, stop_process, wait_for_port

MOSQUITTO = "/usr/sbin/mosquitto"
SCHEMAS = Path(__file__).with_name("vda5050_schemas")
TOPICS = ("connection", "state", "visualization", "factsheet", "order", "instantActions")
#: Real seconds any wait of these tests may take.
WAIT = 20.0


def require_mosquitto() -> str:
    """The mosquitto executable; skip when missing, fail if GALILEO_REQUIRE_PEERS=1."""
    found = MOSQUITTO if os.access(MOSQUITTO, os.X_OK) else shutil.which("mosquitto")
    if found is None:
        missing_peer("Mosquitto")
    assert found is not None
    return found


def validators() -> dict[str, jsonschema.Draft202012Validator]:
    """One validator per topic, from the official schemas."""
    result = {}
    for topic in TOPICS:
        schema = json.loads((SCHEMAS / f"{topic}.schema").read_text())
        result[topic] = jsonschema.Draft202012Validator(schema)
    return result


VALIDATORS = validators()


def make_certificate(directory: Path) -> tuple[Path, Path]:
    """A self-signed certificate for 127.0.0.1 (openssl): (certificate, key)."""
    openssl = shutil.which("openssl")
    if openssl is None:
        missing_peer("openssl")
    assert openssl is not None
    cert, key = directory / "broker.crt", directory / "broker.key"
    subprocess.run(
        [openssl, "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-days", "1",
         "-keyout", str(key), "-out", str(cert), "-subj", "/CN=127.0.0.1",
         "-addext", "subjectAltName=IP:127.0.0.1"],
        check=True, capture_output=True, timeout=60,
    )  # fmt: skip
    return cert, key


class Broker:
    """A real Mosquitto on 127.0.0.1 (optionally TLS); stop() and start() keep the port."""

    def __init__(self, directory: Path, *, tls: bool = False) -> None:
        self.executable = require_mosquitto()
        self.directory = directory
        self.port = free_port()
        self.tls = tls
        self.cert: Path | None = None
        self.proc: asyncio.subprocess.Process | None = None

    @property
    def url(self) -> str:
        """The broker URL a vehicle connects to."""
        return f"{'mqtts' if self.tls else 'mqtt'}://127.0.0.1:{self.port}"

    def _config(self) -> Path:
        lines = [
            f"listener {self.port} 127.0.0.1", "allow_anonymous true", "persistence false",
            # As root, Mosquitto drops to its own user, which cannot read files under tmp_path.
            f"user {getpass.getuser()}",
        ]  # fmt: skip
        if self.tls:
            self.cert, key = make_certificate(self.directory)
            lines += [f"certfile {self.cert}", f"keyfile {key}"]
        path = self.directory / f"mosquitto-{self.port}.conf"
        path.write_text("\n".join(lines) + "\n")
        return path

    async def start(self) -> None:
        """Start the broker and wait until it accepts connections."""
        config = self._config()
        log = (self.directory / f"mosquitto-{self.port}.log").open("ab")
        try:
            self.proc = await asyncio.create_subprocess_exec(
                self.executable, "-c", str(config),
                stdin=asyncio.subprocess.DEVNULL, stdout=log, stderr=log,
            )  # fmt: skip
        finally:
            log.close()
        await wait_for_port(self.port, 10.0)

    async def stop(self) -> None:
        """Stop the broker (idempotent)."""
        if self.proc is not None:
            proc, self.proc = self.proc, None
            await stop_process(proc)

    @classmethod
    @contextlib.asynccontextmanager
    async def running(cls, directory: Path, *, tls: bool = False) -> AsyncIterator[Broker]:
        """A started broker, stopped on exit whatever happens."""
        broker = cls(directory, tls=tls)
        try:
            await broker.start()
            yield broker
        finally:
            await broker.stop()


@pytest.fixture(name="broker")
async def broker_fixture(tmp_path: Path) -> AsyncIterator[Broker]:
    """A running broker for one test (import ``broker_fixture`` to use it as ``broker``)."""
    async with Broker.running(tmp_path) as running:
        yield running


class Master:
    """A master control: sends orders and instant actions, validates all it receives."""

    def __init__(self, client: aiomqtt.Client, prefix: str) -> None:
        self.client = client
        self.prefix = prefix
        self.received: dict[str, list[dict[str, Any]]] = {topic: [] for topic in TOPICS}
        self._arrived = anyio.Event()
        self._header = 0

    @classmethod
    @contextlib.asynccontextmanager
    async def connected(
        cls, broker: Broker, manufacturer: str = "acme", serial: str = "r1"
    ) -> AsyncIterator[Master]:
        """A master subscribed to the vehicle's topics."""
        tls = None
        if broker.tls:
            import ssl

            tls = ssl.create_default_context(cafile=str(broker.cert))
        async with aiomqtt.Client(
            "127.0.0.1", broker.port, identifier=f"master-{serial}", tls_context=tls
        ) as client:
            master = cls(client, f"uagv/v2/{manufacturer}/{serial}")
            await client.subscribe(f"{master.prefix}/+", qos=1)
            async with anyio.create_task_group() as group:
                group.start_soon(master._receive)
                try:
                    yield master
                finally:
                    group.cancel_scope.cancel()

    async def _receive(self) -> None:
        with contextlib.suppress(aiomqtt.MqttError):
            async for message in self.client.messages:
                topic = str(message.topic).rsplit("/", 1)[-1]
                assert isinstance(message.payload, (bytes, bytearray))
                body = json.loads(message.payload)
                if topic in ("order", "instantActions"):
                    continue
                VALIDATORS[topic].validate(body)  # every published message follows the schema
                self.received[topic].append(body)
                self._arrived.set()
                self._arrived = anyio.Event()

    async def wait_for(
        self, topic: str, predicate: Callable[[dict[str, Any]], bool], what: str = ""
    ) -> dict[str, Any]:
        """The first message on ``topic`` (already received or next) where ``predicate`` holds."""
        seen = 0
        with anyio.fail_after(WAIT):
            while True:
                messages = self.received[topic]
                for message in messages[seen:]:
                    if predicate(message):
                        return message
                seen = len(messages)
                await self._arrived.wait()
        raise AssertionError(what)  # pragma: no cover - fail_after raises first

    async def next_state(
        self, predicate: Callable[[dict[str, Any]], bool], since: dict[str, Any] | None = None
    ) -> dict[str, Any]:
        """The first state published from now on (or after ``since``) where ``predicate`` holds."""
        states = self.received["state"]
        start = len(states)
        if since is not None:
            start = next(i for i, state in enumerate(states) if state is since) + 1
        with anyio.fail_after(WAIT):
            while True:
                for message in self.received["state"][start:]:
                    if predicate(message):
                        return message
                start = len(self.received["state"])
                await self._arrived.wait()
        raise AssertionError  # pragma: no cover

    def _stamp(self) -> dict[str, Any]:
        self._header += 1
        manufacturer, serial = self.prefix.split("/")[2:4]
        return {
            "headerId": self._header, "timestamp": "2026-01-01T00:00:00.000Z",
            "version": "2.0.0", "manufacturer": manufacturer, "serialNumber": serial,
        }  # fmt: skip

    async def send(self, topic: str, body: dict[str, Any], *, validate: bool = True) -> None:
        """Publish ``body`` (with a header) on the vehicle's ``topic``."""
        message = {**self._stamp(), **body}
        if validate:
            VALIDATORS[topic].validate(message)
        await self.client.publish(f"{self.prefix}/{topic}", json.dumps(message), qos=1)

    async def order(self, order_id: str, nodes: list[dict[str, Any]], update: int = 0) -> None:
        """Send an order through ``nodes`` (edges joining them, all released)."""
        await self.send("order", make_order(order_id, nodes, update))

    async def instant(self, *actions: tuple[str, str]) -> None:
        """Send instant actions given as (actionId, actionType)."""
        body = [{"actionId": a, "actionType": t, "blockingType": "HARD"} for a, t in actions]
        await self.send("instantActions", {"actions": body})


def node(
    node_id: str, x: float | None = None, y: float | None = None, *, seq: int = 0,
    released: bool = True, **position: Any,
) -> dict[str, Any]:  # fmt: skip
    """A node; with x and y it has a nodePosition on map "map"."""
    result: dict[str, Any] = {
        "nodeId": node_id,
        "sequenceId": seq,
        "released": released,
        "actions": [],
    }
    if x is not None and y is not None:
        result["nodePosition"] = {"x": x, "y": y, "mapId": "map", **position}
    return result


def make_order(
    order_id: str, nodes: list[dict[str, Any]], update: int = 0, first_seq: int = 0
) -> dict[str, Any]:
    """An order through ``nodes``: sequence ids counted from ``first_seq``, edges joining them."""
    nodes = [dict(n, sequenceId=first_seq + 2 * i) for i, n in enumerate(nodes)]
    edges = [
        {"edgeId": f"e{a['nodeId']}-{b['nodeId']}", "sequenceId": a["sequenceId"] + 1,
         "released": b["released"], "startNodeId": a["nodeId"], "endNodeId": b["nodeId"],
         "actions": []}
        for a, b in itertools.pairwise(nodes)
    ]  # fmt: skip
    return {"orderId": order_id, "orderUpdateId": update, "nodes": nodes, "edges": edges}


def error_types(state: dict[str, Any]) -> list[str]:
    """The errorTypes of a state message."""
    return [error["errorType"] for error in state["errors"]]


__all__ = [
    "MOSQUITTO",
    "WAIT",
    "Broker",
    "Master",
    "broker_fixture",
    "error_types",
    "make_certificate",
    "make_order",
    "node",
    "require_mosquitto",
]
