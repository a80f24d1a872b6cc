"""Helpers for the VDA 5050 tests: a real Mosquitto broker and a master control client."""

from __future__ import annotations

import asyncio
import contextlib
import getpass
import itertools
import json
import os
import shutil
import ssl
import subprocess
from collections.abc import AsyncIterator, Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import aiomqtt
import anyio
import jsonschema
import pytest

from tests.support.peers import missing_peer
from tests.support.ros_support import free_port, stop_process, wait_for_port

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


def validators(directory: Path = SCHEMAS) -> dict[str, jsonschema.Draft202012Validator]:
    """One validator per topic, from the official schemas in ``directory``."""
    result = {}
    for topic in TOPICS:
        schema = json.loads((directory / f"{topic}.schema").read_text())
        result[topic] = jsonschema.Draft202012Validator(schema)
    return result


VALIDATORS = validators()
#: The validators of each protocol version (a message's ``version`` field picks them).
VERSIONS = {"2.0.0": VALIDATORS, "2.1.0": validators(SCHEMAS / "2.1.0")}


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


def _openssl(*args: str) -> None:
    openssl = shutil.which("openssl")
    if openssl is None:
        missing_peer("openssl")
    assert openssl is not None
    subprocess.run([openssl, *args], check=True, capture_output=True, timeout=60)


@dataclass(frozen=True)
class MutualTls:
    """A test CA and what it signed: the broker's certificate (127.0.0.1) and a client's."""

    ca: Path
    server_cert: Path
    server_key: Path
    client_cert: Path
    client_key: Path

    def client_context(self) -> ssl.SSLContext:
        """A TLS context that trusts the CA and presents the client certificate."""
        context = ssl.create_default_context(cafile=str(self.ca))
        context.load_cert_chain(str(self.client_cert), str(self.client_key))
        return context


def make_mutual_tls(directory: Path) -> MutualTls:
    """A CA, a broker certificate for 127.0.0.1 and a client certificate it signed (openssl)."""
    ca, ca_key = directory / "ca.crt", directory / "ca.key"
    _openssl("req", "-x509", "-newkey", "rsa:2048", "-nodes", "-days", "1", "-keyout",
             str(ca_key), "-out", str(ca), "-subj", "/CN=galileo-test-ca")  # fmt: skip
    extensions = directory / "server.ext"
    extensions.write_text("subjectAltName=IP:127.0.0.1\n")
    signed = {}
    for name, subject in (("server", "/CN=127.0.0.1"), ("client", "/CN=acme-r1")):
        key, request, cert = (directory / f"{name}.{ext}" for ext in ("key", "csr", "crt"))
        _openssl("req", "-newkey", "rsa:2048", "-nodes", "-keyout", str(key), "-out",
                 str(request), "-subj", subject)  # fmt: skip
        extra = ["-extfile", str(extensions)] if name == "server" else []
        _openssl("x509", "-req", "-in", str(request), "-CA", str(ca), "-CAkey", str(ca_key),
                 "-CAcreateserial", "-days", "1", "-out", str(cert), *extra)  # fmt: skip
        signed[name] = (cert, key)
    return MutualTls(ca, *signed["server"], *signed["client"])


def password_file(directory: Path, logins: dict[str, str]) -> Path:
    """A Mosquitto password file for ``logins`` (user: password), hashed by mosquitto_passwd."""
    tool = shutil.which("mosquitto_passwd")
    if tool is None:
        missing_peer("mosquitto_passwd")
    assert tool is not None
    path = directory / "mosquitto.passwd"
    path.write_text("".join(f"{user}:{password}\n" for user, password in logins.items()))
    subprocess.run([tool, "-U", str(path)], check=True, capture_output=True, timeout=60)
    return path


class Broker:
    """A real Mosquitto on 127.0.0.1 (optionally TLS); stop() and start() keep the port.

    ``mutual``: TLS that requires a client certificate signed by its CA. ``logins``: only
    these users (user: password) may connect; the master logs in as the first one.
    ``extra``: more lines of its configuration (a bridge).
    """

    def __init__(
        self, directory: Path, *, tls: bool = False, mutual: MutualTls | None = None,
        logins: dict[str, str] | None = None, extra: tuple[str, ...] = (),
    ) -> None:  # fmt: skip
        self.executable = require_mosquitto()
        self.directory = directory
        self.port = free_port()
        self.tls = tls or mutual is not None
        self.mutual = mutual
        self.logins = logins
        self.extra = extra
        self.cert: Path | None = None if mutual is None else mutual.ca
        self.proc: asyncio.subprocess.Process | None = None

    @property
    def url(self) -> str:
        """The broker URL a vehicle connects to."""
        return f"{'mqtts' if self.tls else 'mqtt'}://127.0.0.1:{self.port}"

    def _config(self) -> Path:
        lines = [
            f"listener {self.port} 127.0.0.1", "persistence false",
            f"allow_anonymous {'false' if self.logins else 'true'}",
            # As root, Mosquitto drops to its own user, which cannot read files under tmp_path.
            f"user {getpass.getuser()}",
        ]  # fmt: skip
        if self.logins:
            lines.append(f"password_file {password_file(self.directory, self.logins)}")
        if self.mutual is not None:
            mutual = self.mutual
            lines += [f"cafile {mutual.ca}", f"certfile {mutual.server_cert}",
                      f"keyfile {mutual.server_key}", "require_certificate true"]  # fmt: skip
        elif self.tls:
            self.cert, key = make_certificate(self.directory)
            lines += [f"certfile {self.cert}", f"keyfile {key}"]
        lines += self.extra
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
    async def running(
        cls, directory: Path, *, tls: bool = False, mutual: MutualTls | None = None,
        logins: dict[str, str] | None = None, extra: tuple[str, ...] = (),
    ) -> AsyncIterator[Broker]:  # fmt: skip
        """A started broker, stopped on exit whatever happens."""
        broker = cls(directory, tls=tls, mutual=mutual, logins=logins, extra=extra)
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

    def __init__(self, client: aiomqtt.Client, prefix: str, version: str = "2.0.0") -> None:
        self.client = client
        self.prefix = prefix
        #: The protocol version this master speaks and expects every message in.
        self.version = version
        self.received: dict[str, list[dict[str, Any]]] = {topic: [] for topic in TOPICS}
        self._arrived = anyio.Event()
        self._header = 0

    @classmethod
    @contextlib.asynccontextmanager
    async def connected(
        cls, broker: Broker, manufacturer: str = "acme", serial: str = "r1",
        version: str = "2.0.0",
    ) -> AsyncIterator[Master]:  # fmt: skip
        """A master subscribed to the vehicle's topics."""
        tls = None
        if broker.mutual is not None:
            tls = broker.mutual.client_context()
        elif broker.tls:
            tls = ssl.create_default_context(cafile=str(broker.cert))
        user, password = next(iter(broker.logins.items())) if broker.logins else (None, None)
        async with aiomqtt.Client(
            "127.0.0.1", broker.port, identifier=f"master-{serial}", tls_context=tls,
            username=user, password=password,
        ) as client:  # fmt: skip
            master = cls(client, f"uagv/v2/{manufacturer}/{serial}", version)
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
                assert body["version"] == self.version, body
                # Every published message follows the schema of its version.
                VERSIONS[self.version][topic].validate(body)
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
            "version": self.version, "manufacturer": manufacturer, "serialNumber": serial,
        }  # fmt: skip

    async def send(self, topic: str, body: dict[str, Any], *, validate: bool = True) -> None:
        """Publish ``body`` (with a header) on the vehicle's ``topic``."""
        message = {**self._stamp(), **body}
        if validate:
            VERSIONS[self.version][topic].validate(message)
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


def bridge_to(central: Broker, name: str = "site") -> tuple[str, ...]:
    """Configuration lines that bridge a broker's VDA 5050 topics both ways to ``central``."""
    return (
        f"connection {name}", f"address 127.0.0.1:{central.port}", "topic uagv/# both 1",
        "cleansession true", "restart_timeout 1", "bridge_protocol_version mqttv311",
    )  # fmt: skip


def error_types(state: dict[str, Any]) -> list[str]:
    """The errorTypes of a state message."""
    return [error["errorType"] for error in state["errors"]]


__all__ = [
    "MOSQUITTO",
    "WAIT",
    "Broker",
    "Master",
    "MutualTls",
    "bridge_to",
    "broker_fixture",
    "error_types",
    "make_certificate",
    "make_mutual_tls",
    "make_order",
    "node",
    "password_file",
    "require_mosquitto",
]
