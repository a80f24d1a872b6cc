"""Broker credentials: the password kept apart and never shown; mutual TLS on a real broker."""

from __future__ import annotations

import asyncio
import logging
import os
import signal
import sys
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from pathlib import Path
from typing import Any

import anyio
import pytest
from pydantic import SecretStr

import galileo_async as galileo
from galileo_async.errors import InvalidArgument
from galileo_async.vda5050 import Vehicle, VehicleConfig, parse_broker_url, redact_url
from galileo_async.vda5050.session import MQTT_LOGGER, tls_context
from tests.cli.test_cli import invoke
from tests.support.ros_support import stop_process
from tests.support.vda5050_support import WAIT, Broker, Master, MutualTls, make_mutual_tls
from tests.vda5050.test_vda5050_vehicle import FAST_SIM, vehicle_on

SECRET = "hunter2-Galileo"
#: The broker's users: the master control logs in first, the vehicle second.
LOGINS = {"master": "master-pw", "vehicle": SECRET}
ONLINE = "ONLINE"


def config(**options: Any) -> VehicleConfig:
    base = {"broker": "mqtt://vehicle@127.0.0.1", "manufacturer": "acme", "serial_number": "r1"}
    return VehicleConfig(**{**base, **options})


# --- the password never shows ----------------------------------------------------------------


@pytest.mark.parametrize("given", ["str", "SecretStr", "url"])
def test_the_password_shows_as_stars_in_every_repr_and_str(given: str) -> None:
    if given == "url":
        made = config(broker=f"mqtt://vehicle:{SECRET}@127.0.0.1")
    else:
        made = config(password=SECRET if given == "str" else SecretStr(SECRET))
    address = made.address
    for text in (repr(made), str(made), repr(address), str(address), f"{made}", f"{address!r}"):
        assert SECRET not in text
        assert "***" in text
    assert address.username == "vehicle"
    assert address.password is not None
    assert address.password.get_secret_value() == SECRET
    assert isinstance(made.password, SecretStr) or given == "url"


@pytest.mark.parametrize(
    "url",
    [
        f"mqtt://u:{SECRET}@host:99999", f"mqtt://u:{SECRET}@[::1", f"http://u:{SECRET}@host",
        f"u:{SECRET}@host", f"mqtt://u:{SECRET}@host/path", f"mqtt://u:{SECRET}@",
        f"mqtt://u:{SECRET}/x@host:1", f"mqtt://u:{SECRET}@h?x=1",
    ],
)  # fmt: skip
def test_broker_url_errors_hide_the_password(url: str) -> None:
    for attempt in (lambda: parse_broker_url(url), lambda: config(broker=url)):
        with pytest.raises(InvalidArgument) as caught:
            attempt()
        assert SECRET not in str(caught.value)
        assert "u:***@" in str(caught.value)


def test_a_config_of_the_wrong_type_is_not_echoed() -> None:
    with pytest.raises(InvalidArgument) as caught:
        Vehicle(None, {"broker": f"mqtt://u:{SECRET}@h"})  # type: ignore[arg-type]
    assert SECRET not in str(caught.value)
    assert "got a dict" in str(caught.value)


def test_redact_url() -> None:
    assert redact_url("mqtts://me:p%40ss@broker:8883") == "mqtts://me:***@broker:8883"
    assert redact_url("mqtt://me:a@b@host") == "mqtt://me:***@host"  # a raw "@" in it
    assert redact_url("mqtt://me@host") == "mqtt://me@host"  # no password
    assert redact_url("mqtt://host:1883") == "mqtt://host:1883"


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"broker": f"mqtt://vehicle:{SECRET}@h", "password": "x"}, "password is given too"),
        ({"broker": "mqtt://h", "password": SECRET}, "needs a user name"),
        ({"broker": f"mqtt://:{SECRET}@h"}, "needs a user name"),
        ({"password": 1234}, "str or a SecretStr"),
        ({"tls_cert_file": "client.crt"}, "need an mqtts://"),
        ({"tls_ca_file": "ca.crt"}, "need an mqtts://"),
        ({"broker": "mqtts://h", "tls_key_file": "client.key"}, "needs tls_cert_file"),
        ({"broker": "mqtts://h", "tls_cert_file": ""}, "tls_cert_file must be a file path"),
    ],
)
def test_inconsistent_credentials_are_refused(options: dict[str, Any], message: str) -> None:
    with pytest.raises(InvalidArgument, match=message) as caught:
        config(**options)
    assert SECRET not in str(caught.value)


def test_unreadable_tls_files_are_refused_before_connecting(tmp_path: Path) -> None:
    missing = config(broker="mqtts://h", tls_cert_file=str(tmp_path / "missing.crt"))
    with pytest.raises(InvalidArgument, match=r"missing\.crt"):
        tls_context(missing)
    assert tls_context(config()) is None  # mqtt://: no TLS


# --- real brokers ------------------------------------------------------------------------------


class WarningSeen(logging.Handler):
    """Sets an event at the first WARNING of the vehicle's session (its broker connection)."""

    def __init__(self) -> None:
        super().__init__(logging.WARNING)
        self.seen = anyio.Event()
        self.records: list[logging.LogRecord] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.records.append(record)
        self.seen.set()


@asynccontextmanager
async def warnings_of_vehicles() -> AsyncIterator[WarningSeen]:
    handler = WarningSeen()
    logger = logging.getLogger("galileo_async.vda5050.session")
    logger.addHandler(handler)
    try:
        yield handler
    finally:
        logger.removeHandler(handler)


@pytest.fixture(name="mutual", scope="module")
def mutual_fixture(tmp_path_factory: pytest.TempPathFactory) -> MutualTls:
    return make_mutual_tls(tmp_path_factory.mktemp("pki"))


async def test_mutual_tls_connects_with_the_client_certificate(
    tmp_path: Path, mutual: MutualTls
) -> None:
    files = {"tls_ca_file": str(mutual.ca), "tls_cert_file": str(mutual.client_cert),
             "tls_key_file": str(mutual.client_key)}  # fmt: skip
    async with (
        Broker.running(tmp_path, mutual=mutual) as broker,
        Master.connected(broker) as master,
        galileo.connect(FAST_SIM) as robot,
        vehicle_on(broker, robot, **files) as vehicle,
    ):
        await master.wait_for("connection", lambda m: m["connectionState"] == ONLINE)
        assert vehicle.session.last_error is None


async def test_mutual_tls_without_a_client_certificate_fails_clearly(
    tmp_path: Path, mutual: MutualTls, caplog: pytest.LogCaptureFixture
) -> None:
    caplog.set_level(logging.DEBUG, logger="galileo_async.vda5050")
    async with (
        Broker.running(tmp_path, mutual=mutual) as broker,
        galileo.connect(FAST_SIM) as robot,
        warnings_of_vehicles() as warnings,
        vehicle_on(broker, robot, tls_ca_file=str(mutual.ca)) as vehicle,
    ):
        with anyio.fail_after(WAIT):
            await warnings.seen.wait()
        assert not vehicle.connected
    message = warnings.records[0].getMessage()
    assert "certificate required" in message
    assert "--tls-cert" in message
    assert vehicle.session.last_error is not None
    assert "certificate required" in vehicle.session.last_error


@pytest.mark.parametrize("given", ["str", "SecretStr", "url"])
async def test_the_password_reaches_the_broker_and_no_log_line(
    tmp_path: Path, caplog: pytest.LogCaptureFixture, given: str
) -> None:
    caplog.set_level(logging.DEBUG, logger="galileo_async.vda5050")
    caplog.set_level(logging.DEBUG, logger=MQTT_LOGGER)  # every packet the client sends
    login = f"vehicle:{SECRET}" if given == "url" else "vehicle"
    password = {"str": SECRET, "SecretStr": SecretStr(SECRET), "url": None}[given]
    async with (
        Broker.running(tmp_path, logins=LOGINS) as broker,
        Master.connected(broker) as master,
        galileo.connect(FAST_SIM) as robot,
        warnings_of_vehicles() as warnings,
    ):
        user_url = broker.url.replace("://", "://vehicle@")
        wrong = VehicleConfig(user_url, "acme", "r0", password="wrong")
        async with anyio.create_task_group() as group:
            group.start_soon(Vehicle(robot, wrong).run)
            with anyio.fail_after(WAIT):
                await warnings.seen.wait()  # refused: not authorized
            group.cancel_scope.cancel()
        assert "Not authorized" in warnings.records[0].getMessage()
        made = VehicleConfig(broker.url.replace("://", f"://{login}@"), "acme", "r1",
                             password=password)  # fmt: skip
        async with anyio.create_task_group() as group:
            group.start_soon(Vehicle(robot, made).run)
            await master.wait_for("connection", lambda m: m["connectionState"] == ONLINE)
            group.cancel_scope.cancel()
    logged = "\n".join(record.getMessage() for record in caplog.records)
    assert "Not authorized" in logged
    assert "check the user name and the password" in logged
    assert "Sending CONNECT" in logged
    assert SECRET not in logged


# --- the command line ---------------------------------------------------------------------------


async def _galileo_vda5050(
    broker: Broker, *options: str, user: str = "vehicle", env: dict[str, str] | None = None
) -> asyncio.subprocess.Process:
    url = broker.url.replace("://", f"://{user}@") if user else broker.url
    environment = {k: v for k, v in os.environ.items() if k != "GALILEO_MQTT_PASSWORD"}
    return await asyncio.create_subprocess_exec(
        sys.executable, "-m", "galileo_async", "--port", FAST_SIM, "vda5050", "--broker", url,
        "--manufacturer", "acme", "--serial-number", "r1", *options,
        stdin=asyncio.subprocess.DEVNULL, stdout=asyncio.subprocess.DEVNULL,
        stderr=asyncio.subprocess.PIPE, env={**environment, **(env or {})},
    )  # fmt: skip


async def _stderr_until(proc: asyncio.subprocess.Process, text: str) -> str:
    """stderr of ``proc`` up to the line that contains ``text``."""
    assert proc.stderr is not None
    seen = ""
    with anyio.fail_after(WAIT):
        while text not in seen:
            line = await proc.stderr.readline()
            assert line, f"stderr ended before {text!r}: {seen!r}"
            seen += line.decode()
    return seen


async def _stop(proc: asyncio.subprocess.Process) -> str:
    """Ctrl-C, exit code 0, and the rest of stderr."""
    proc.send_signal(signal.SIGINT)
    with anyio.fail_after(WAIT):
        _, rest = await proc.communicate()
    assert proc.returncode == 0, rest
    return rest.decode()


@pytest.mark.parametrize("given", ["environment", "file", "url"])
async def test_cli_password_reaches_the_broker(tmp_path: Path, given: str) -> None:
    options: list[str] = []
    env: dict[str, str] = {}
    user = "vehicle"
    if given == "environment":
        env["GALILEO_MQTT_PASSWORD"] = SECRET
    elif given == "file":
        secret_file = tmp_path / "mqtt-password"
        secret_file.write_text(SECRET + "\n")
        options += ["--password-file", str(secret_file)]
    else:
        user = f"vehicle:{SECRET}"
    async with Broker.running(tmp_path, logins=LOGINS) as broker, Master.connected(broker) as m:
        proc = await _galileo_vda5050(broker, *options, user=user, env=env)
        try:
            stderr = await _stderr_until(proc, "Ctrl-C stops")
            await m.wait_for("connection", lambda message: message["connectionState"] == ONLINE)
            stderr += await _stop(proc)
        finally:
            await stop_process(proc)
    assert SECRET not in stderr
    assert "vehicle:***@127.0.0.1" in stderr if given == "url" else "vehicle@127.0.0.1" in stderr
    warned = "other users of this machine can read" in stderr
    assert warned == (given == "url")


async def test_cli_shows_why_the_broker_refuses(tmp_path: Path, mutual: MutualTls) -> None:
    (tmp_path / "login").mkdir()
    (tmp_path / "tls").mkdir()
    async with (
        Broker.running(tmp_path / "login", logins=LOGINS) as login,
        Broker.running(tmp_path / "tls", mutual=mutual) as tls,
    ):
        wrong = await _galileo_vda5050(login, env={"GALILEO_MQTT_PASSWORD": "wrong"})
        no_cert = await _galileo_vda5050(tls, "--ca-file", str(mutual.ca), user="")
        try:
            refused = await _stderr_until(wrong, "Not authorized")
            assert "check the user name and the password" in refused
            assert await _stderr_until(no_cert, "certificate required")
            for proc in (wrong, no_cert):
                await _stop(proc)
        finally:
            await stop_process(wrong)
            await stop_process(no_cert)


@pytest.mark.parametrize(
    ("args", "env", "message"),
    [
        (["--broker", "mqtt://vehicle@127.0.0.1"], {"GALILEO_MQTT_PASSWORD": ""},
         "GALILEO_MQTT_PASSWORD is set but empty"),
        (["--broker", "mqtt://vehicle@127.0.0.1", "--password-file", "{tmp}/none"], {},
         "cannot read --password-file"),
        (["--broker", "mqtt://vehicle@127.0.0.1", "--password-file", "{tmp}/empty"], {},
         "is empty"),
        (["--broker", f"mqtt://vehicle:{SECRET}@127.0.0.1"], {"GALILEO_MQTT_PASSWORD": "x"},
         "password is given too"),
        (["--broker", f"mqtt://vehicle:{SECRET}@127.0.0.1:99999"], {}, "vehicle:***@"),
        (["--broker", "mqtt://127.0.0.1"], {"GALILEO_MQTT_PASSWORD": SECRET},
         "needs a user name"),
        (["--broker", "mqtts://127.0.0.1", "--tls-cert", "{tmp}/none.crt"], {},
         "cannot load the TLS files"),
        (["--broker", "mqtt://127.0.0.1", "--tls-cert", "{tmp}/none.crt"], {},
         "need an mqtts://"),
    ],
)  # fmt: skip
def test_cli_refuses_bad_credentials_before_connecting(
    args: list[str], env: dict[str, str], message: str, tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
) -> None:  # fmt: skip
    (tmp_path / "empty").write_text("\n")
    for name, value in env.items():
        monkeypatch.setenv(name, value)
    if "GALILEO_MQTT_PASSWORD" not in env:
        monkeypatch.delenv("GALILEO_MQTT_PASSWORD", raising=False)
    common = ["--manufacturer", "acme", "--serial-number", "r1"]
    filled = [arg.format(tmp=tmp_path) for arg in args]
    result = invoke("vda5050", *filled, *common, port="/dev/nonexistent-galileo")
    assert result.exit_code == 2, result.output
    assert message in result.output
    assert SECRET not in result.output
