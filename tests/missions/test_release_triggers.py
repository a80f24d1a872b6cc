"""``--release NAME=http:…`` and ``NAME=mqtt:…``: triggers served while a mission runs."""

from __future__ import annotations

import json
import sys
import urllib.request
from pathlib import Path

import aiohttp
import aiomqtt
import anyio
import pytest

from galileo_async.cli import ExitCode
from galileo_async.cli.releases import Release, parse_releases, triggered
from tests.cli.test_cli import invoke
from tests.cli.test_cli_served import _read_until as read_until
from tests.cli.test_cli_signals import start
from tests.missions.test_mission_run_cli import FLEET, write
from tests.support.ros_support import free_port
from tests.support.vda5050_support import Broker, require_mosquitto

pytestmark = pytest.mark.timeout(120)

#: Real seconds any wait of these tests may take.
WAIT = 30.0
WAITING = {"mission": "m", "steps": [{"wait": "operator"}, {"goto": 1}]}


async def post(port: int, name: str) -> tuple[int, object]:
    """POST /release/NAME to the loopback server at ``port``: (status, JSON body)."""
    async with (
        aiohttp.ClientSession() as session,
        session.post(f"http://127.0.0.1:{port}/release/{name}") as response,
    ):
        return response.status, await response.json()


async def released(release: Release) -> bool:
    """True once ``release`` returned; False if it is still waiting when all else blocks."""
    done = anyio.Event()

    async def take() -> None:
        await release()
        done.set()

    async with anyio.create_task_group() as group:
        group.start_soon(take)
        await anyio.wait_all_tasks_blocked()
        group.cancel_scope.cancel()
    return done.is_set()


async def test_a_post_releases_its_wait_and_an_unknown_name_is_404() -> None:
    port = free_port()
    specs = [f"a=http:127.0.0.1:{port}", f"b=http:{port}"]
    async with triggered(parse_releases(specs)) as given:
        assert not await released(given["a"])
        assert await post(port, "a") == (200, {"released": "a"})
        with anyio.fail_after(WAIT):
            await given["a"]()
        assert await post(port, "nope") == (404, {"error": "no release 'nope' here"})
        assert not await released(given["b"])


async def test_posts_before_the_wait_are_remembered_once() -> None:
    port = free_port()
    async with triggered(parse_releases([f"a=http:127.0.0.1:{port}"])) as given:
        await post(port, "a")
        await post(port, "a")
        with anyio.fail_after(WAIT):
            await given["a"]()
        assert not await released(given["a"])


async def test_the_server_is_closed_on_exit_and_on_cancellation() -> None:
    port = free_port()
    async with triggered(parse_releases([f"a=http:127.0.0.1:{port}"])):
        assert (await post(port, "a"))[0] == 200
    with pytest.raises(aiohttp.ClientConnectionError):
        await post(port, "a")
    with anyio.CancelScope() as scope:
        async with triggered(parse_releases([f"a=http:127.0.0.1:{port}"])) as given:
            scope.cancel()
            await given["a"]()
    assert scope.cancelled_caught
    with pytest.raises(aiohttp.ClientConnectionError):
        await post(port, "a")


@pytest.mark.parametrize(
    ("spec", "message"),
    [
        ("operator=http:", "'' is not a port"),
        ("operator=http:127.0.0.1:x", "'x' is not a port"),
        ("operator=http:70000", "'70000' is not a port"),
        ("operator=mqtt:mqtt://127.0.0.1", "give mqtt:mqtt://HOST[:PORT]/TOPIC"),
        ("operator=mqtt:http://127.0.0.1/go", "give mqtt:mqtt://HOST[:PORT]/TOPIC"),
        ("operator=mqtt:mqtt://127.0.0.1:x/go", "has a bad port"),
        ("operator=ftp:x", "give NAME=key"),
    ],
)
def test_a_bad_spec_exits_2_naming_it(tmp_path: Path, spec: str, message: str) -> None:
    plan = write(tmp_path, WAITING)
    result = invoke("mission", "run", plan, "--release", spec, port=None)
    assert result.exit_code == ExitCode.USAGE, result.output
    assert repr(spec) in result.output
    assert message in result.output


def test_a_post_releases_the_wait_of_a_run(tmp_path: Path) -> None:
    port = free_port()
    plan = write(tmp_path, WAITING)
    process = start(
        "--port", "sim://?speed=20", "mission", "run", plan,
        "--release", f"operator=http:127.0.0.1:{port}",
    )  # fmt: skip
    try:
        assert process.stderr is not None
        read_until(process.stderr, f"release operator: POST http://127.0.0.1:{port}/release/", WAIT)
        request = urllib.request.Request(f"http://127.0.0.1:{port}/release/operator", method="POST")
        with urllib.request.urlopen(request, timeout=WAIT) as response:
            assert json.load(response) == {"released": "operator"}
        out, err = process.communicate(timeout=WAIT)
    finally:
        process.kill()
        process.communicate()
    assert process.returncode == 0, err
    assert "steps[0] wait done" in out


async def test_a_message_releases_its_wait(tmp_path: Path) -> None:
    require_mosquitto()
    async with Broker.running(tmp_path) as broker:
        specs = [
            f"a=mqtt:mqtt://127.0.0.1:{broker.port}/site/a",
            f"b=mqtt:mqtt://127.0.0.1:{broker.port}/site/b",
        ]
        async with (
            triggered(parse_releases(specs)) as given,
            aiomqtt.Client("127.0.0.1", broker.port) as client,
        ):
            assert not await released(given["a"])
            await client.publish("site/a", b"go", qos=1)
            await client.publish("site/a", b"go", qos=1)
            with anyio.fail_after(WAIT):
                await given["a"]()
            assert not await released(given["a"])
            assert not await released(given["b"])


async def test_the_mqtt_client_ends_on_cancellation(tmp_path: Path) -> None:
    require_mosquitto()
    async with Broker.running(tmp_path) as broker:
        spec = f"a=mqtt:mqtt://127.0.0.1:{broker.port}/site/a"
        with anyio.CancelScope() as scope:
            async with triggered(parse_releases([spec])) as given:
                scope.cancel()
                await given["a"]()
        assert scope.cancelled_caught


def test_a_message_releases_the_wait_of_a_run(tmp_path: Path) -> None:
    require_mosquitto()
    plan = write(tmp_path, WAITING)

    async def main() -> tuple[int, str, str]:
        async with Broker.running(tmp_path) as broker:
            process = start(
                "--port", "sim://?speed=20", "mission", "run", plan,
                "--release", f"operator=mqtt:mqtt://127.0.0.1:{broker.port}/site/go",
            )  # fmt: skip
            try:
                assert process.stderr is not None
                await anyio.to_thread.run_sync(
                    read_until, process.stderr, "release on mqtt://127.0.0.1", WAIT
                )
                async with aiomqtt.Client("127.0.0.1", broker.port) as client:
                    await client.publish("site/go", b"", qos=1)
                out, err = await anyio.to_thread.run_sync(lambda: process.communicate(timeout=WAIT))
            finally:
                process.kill()
                process.communicate()
            return process.returncode, out, err

    returncode, out, err = anyio.run(main)
    assert returncode == 0, err
    assert "steps[0] wait done" in out


def test_a_post_releases_the_waits_of_a_fleet_run(tmp_path: Path) -> None:
    port = free_port()
    fleet = tmp_path / "fleet.toml"
    fleet.write_text(FLEET, encoding="utf-8")
    plan = write(tmp_path, WAITING)
    process = start(
        "--fleet", str(fleet), "--json", "fleet", "mission", "run", plan,
        "--release", f"operator=http:{port}",
    )  # fmt: skip
    try:
        assert process.stdout is not None
        # Both robots wait before the POST (readline: both lines may come in one read).
        started = 0
        while started < 2:
            line = process.stdout.readline()
            assert line, "the run ended before both robots waited"
            started += '"step_started"' in line
        request = urllib.request.Request(f"http://127.0.0.1:{port}/release/operator", method="POST")
        with urllib.request.urlopen(request, timeout=WAIT) as response:
            assert response.status == 200
        out, err = process.communicate(timeout=WAIT)
    finally:
        process.kill()
        process.communicate()
    assert process.returncode == 0, err
    ended = [line for line in out.splitlines() if '"mission_ended"' in line]
    assert len(ended) == 2, out


async def test_an_error_of_the_run_leaves_as_itself() -> None:
    port = free_port()
    with pytest.raises(LookupError):
        async with triggered(parse_releases(["a=key", f"b=http:{port}"])):
            raise LookupError("the run's")


@pytest.mark.parametrize(
    ("module", "spec", "extra"),
    [
        ("aiohttp.web", "operator=http:8090", "galileo-async[http]"),
        ("aiomqtt", "operator=mqtt:mqtt://127.0.0.1/go", "galileo-async[vda5050]"),
    ],
)
def test_a_missing_extra_exits_2_naming_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, module: str, spec: str, extra: str
) -> None:
    monkeypatch.setitem(sys.modules, module, None)
    plan = write(tmp_path, WAITING)
    result = invoke("mission", "run", plan, "--release", spec, port=None)
    assert result.exit_code == ExitCode.USAGE, result.output
    assert repr(spec) in result.output
    assert extra in result.output
