"""Fleets of vehicles: one process, many vehicles; bridged brokers; a broker lost mid-order."""

from __future__ import annotations

import asyncio
import signal
import subprocess
import sys
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from functools import partial
from pathlib import Path
from typing import Any

import anyio
import pytest

import galileo_async as galileo
from galileo_async.errors import InvalidArgument
from galileo_async.events import GoalAccepted
from galileo_async.fleet.shards import Shard
from galileo_async.robot import Robot
from galileo_async.vda5050 import FleetVehicle, Vehicle, VehicleConfig, VehicleFleet
from tests.support.ports import refused_port
from tests.support.ros_support import stop_process
from tests.support.vda5050_support import (
    WAIT,
    Broker,
    Master,
    bridge_to,
    broker_fixture,  # noqa: F401 (the broker fixture)
    make_order,
    node,
)

ROOT = Path(__file__).resolve().parents[2]


def config(broker: Broker, serial: str, *fallbacks: Broker, **options: Any) -> VehicleConfig:
    return VehicleConfig(
        broker=broker.url, manufacturer="acme", serial_number=serial,
        fallback_brokers=tuple(b.url for b in fallbacks), **options,
    )  # fmt: skip


@asynccontextmanager
async def running(runnable: Vehicle | VehicleFleet) -> AsyncIterator[None]:
    async with anyio.create_task_group() as group:
        group.start_soon(runnable.run)
        try:
            yield
        finally:
            group.cancel_scope.cancel()


def online(message: dict[str, Any]) -> bool:
    return message["connectionState"] == "ONLINE"


async def test_a_fleet_runs_every_robot_as_its_own_vehicle(broker: Broker) -> None:
    with refused_port() as port:
        robots = {
            name: FleetVehicle(partial(galileo.connect, "sim://?speed=20"), config(broker, name))
            for name in ("r1", "r2", "r3")
        }
        # Never reachable (tried again), and options every try would reject (ended).
        away = partial(galileo.connect, f"socket://127.0.0.1:{port}")
        robots["away"] = FleetVehicle(away, config(broker, "away"))
        bad = partial(galileo.connect, "sim://", stale_timeout=-1.0)
        robots["bad"] = FleetVehicle(bad, config(broker, "bad"))
        fleet = VehicleFleet(robots, retry_initial=0.2, retry_max=0.2)
        async with (
            Master.connected(broker, serial="r1") as m1,
            Master.connected(broker, serial="r2") as m2,
            Master.connected(broker, serial="r3") as m3,
        ):
            async with running(fleet):
                for master in (m1, m2, m3):
                    await master.wait_for("connection", online)
                    await master.wait_for("state", lambda s: True)
                with anyio.fail_after(WAIT):
                    await fleet.wait_tried("bad")
                    await fleet.wait_tried("away")
                assert fleet.ended("bad")
                assert fleet.error("away") is not None
                assert isinstance(fleet.error("bad"), InvalidArgument)
                assert not fleet.ended("away")
                assert set(fleet.vehicles) == {"r1", "r2", "r3"}
                assert all(fleet.vehicle(name).connected for name in ("r1", "r2", "r3"))  # type: ignore[union-attr]
                reports = await fleet.shut_down("the fleet stopped")
                assert list(reports) == ["r1", "r2", "r3"]
                assert all(report.reason == "the fleet stopped" for report in reports.values())
            for master in (m1, m2, m3):
                await master.wait_for("connection", lambda m: m["connectionState"] == "OFFLINE")
            assert all(v.session.offline_published for v in fleet.vehicles.values())


def test_a_fleet_refuses_two_robots_with_one_identity(broker: Broker) -> None:
    same = config(broker, "r1")
    sim = partial(galileo.connect, "sim://")
    with pytest.raises(InvalidArgument, match="'a' and 'b' are both vehicle acme/r1"):
        VehicleFleet({"a": FleetVehicle(sim, same), "b": FleetVehicle(sim, same)})


def test_fallback_brokers_are_checked() -> None:
    with pytest.raises(InvalidArgument, match="given twice"):
        VehicleConfig(
            broker="mqtt://h:1883", manufacturer="m", serial_number="s",
            fallback_brokers=("mqtt://h",),
        )  # fmt: skip
    with pytest.raises(InvalidArgument, match="must start with mqtt://"):
        VehicleConfig(
            broker="mqtt://h", manufacturer="m", serial_number="s", fallback_brokers=("http://x",)
        )
    shown = VehicleConfig(
        broker="mqtt://u@a", manufacturer="m", serial_number="s",
        fallback_brokers=("mqtt://u:secret@b",),
    )  # fmt: skip
    assert "secret" not in repr(shown)
    assert [(a.host, a.port) for a in shown.addresses] == [("a", 1883), ("b", 1883)]


async def test_an_order_through_bridged_brokers(tmp_path: Path) -> None:
    """The vehicle on a site broker, the master on a central one, a bridge between them."""
    (tmp_path / "central").mkdir()
    (tmp_path / "site").mkdir()
    async with (
        Broker.running(tmp_path / "central") as central,
        Broker.running(tmp_path / "site", extra=bridge_to(central)) as site,
        Master.connected(central) as master,
        galileo.connect("sim://?speed=20") as robot,
        running(Vehicle(robot, config(site, "r1"))),
    ):
        await master.wait_for("visualization", lambda m: True)  # the bridge is up
        await robot.start_navigation()
        await master.wait_for("state", lambda s: s["operatingMode"] == "AUTOMATIC")
        await master.order("o1", [node("start", 0.0, 0.0), node("a", 1.0, 0.0)])
        done = await master.next_state(
            lambda s: s["orderId"] == "o1" and s["lastNodeId"] == "a" and not s["driving"]
        )
        assert done["nodeStates"] == []
        assert done["errors"] == []


async def count_goals(robot: Robot, accepted: list[GoalAccepted]) -> None:
    async for event in robot.events():
        if isinstance(event, GoalAccepted):
            accepted.append(event)


async def test_a_broker_lost_mid_order(tmp_path: Path) -> None:
    """The vehicle moves to the next broker: ONLINE and its state there, the order not run twice."""
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    nodes = [node("start", 0.0, 0.0), node("a", 2.0, 0.0), node("b", 2.0, 1.5)]
    accepted: list[GoalAccepted] = []
    async with (
        Broker.running(tmp_path / "a") as first,
        Broker.running(tmp_path / "b") as second,
        Master.connected(first) as on_first,
        Master.connected(second) as on_second,
        galileo.connect("sim://?speed=2") as robot,
        running(Vehicle(robot, config(first, "r1", second))),
        anyio.create_task_group() as group,
    ):
        group.start_soon(count_goals, robot, accepted)
        await on_first.wait_for("connection", online)
        await robot.start_navigation()
        await on_first.wait_for("state", lambda s: s["operatingMode"] == "AUTOMATIC")
        await on_first.order("o1", nodes)
        await on_first.next_state(lambda s: s["orderId"] == "o1" and s["driving"])
        assert first.proc is not None
        first.proc.kill()  # mid-order, no goodbye
        await first.stop()
        assert robot.status is not None
        assert robot.status.goal_active
        hello = await on_second.wait_for("connection", online)
        assert hello["serialNumber"] == "r1"
        there = await on_second.wait_for("state", lambda s: s["orderId"] == "o1")
        assert there["nodeStates"], "the order was still running when the broker went"
        # The master (or a bridge) sends the order again on the new broker: not run twice.
        await on_second.send("order", make_order("o1", nodes))
        done = await on_second.next_state(
            lambda s: s["lastNodeId"] == "b" and not s["nodeStates"] and not s["driving"]
        )
        assert done["orderId"] == "o1"
        assert all(state["errors"] == [] for state in on_second.received["state"])
        sequence = [state["lastNodeSequenceId"] for state in on_second.received["state"]]
        assert sequence == sorted(sequence)  # never back to the start
        assert len(accepted) == len(nodes) - 1  # one goal per node driven to, none again
        assert robot.status is not None
        assert not robot.status.goal_active
        group.cancel_scope.cancel()


FLEET_FILE = """
[robots.alpha]
port = "sim://?speed=20"
serial_number = "A-1"

[robots.beta]
port = "sim://?speed=20"
"""


async def test_the_cli_runs_a_fleet_and_sigterm_shuts_every_vehicle_down(
    broker: Broker, tmp_path: Path
) -> None:
    fleet_file = tmp_path / "fleet.toml"
    fleet_file.write_text(FLEET_FILE)
    log_path = tmp_path / "cli.log"
    async with (
        Master.connected(broker, serial="A-1") as alpha,
        Master.connected(broker, serial="beta") as beta,
    ):
        with log_path.open("ab") as log:
            proc = await asyncio.create_subprocess_exec(
                sys.executable, "-m", "galileo_async", "vda5050", "--fleet", str(fleet_file),
                "--shard", "1/1", "--broker", broker.url, "--manufacturer", "acme",
                stdin=asyncio.subprocess.DEVNULL, stdout=log, stderr=log, cwd=ROOT,
            )  # fmt: skip
        try:
            for master in (alpha, beta):
                await master.wait_for("connection", online)
            proc.send_signal(signal.SIGTERM)
            with anyio.fail_after(WAIT):
                code = await proc.wait()
        finally:
            await stop_process(proc)
        for master in (alpha, beta):
            await master.wait_for("connection", lambda m: m["connectionState"] == "OFFLINE")
    text = log_path.read_text()
    assert code == 0, text
    assert "VDA 5050 fleet: 2 vehicles of" in text
    assert "stopped by SIGTERM: 2 of 2 vehicles shut down; OFFLINE published by 2" in text


def test_the_cli_needs_one_robot_or_a_fleet(tmp_path: Path) -> None:
    base = [sys.executable, "-m", "galileo_async", "vda5050", "--broker", "mqtt://127.0.0.1"]
    both = subprocess.run(
        [*base, "--manufacturer", "m", "--serial-number", "s", "--fleet", str(tmp_path / "f")],
        capture_output=True, text=True, timeout=WAIT, cwd=ROOT,
    )  # fmt: skip
    assert both.returncode == 2
    assert "give --serial-number (one robot) or --fleet FILE" in both.stderr
    (tmp_path / "f.toml").write_text(FLEET_FILE)
    bad_shard = subprocess.run(
        [*base, "--manufacturer", "m", "--fleet", str(tmp_path / "f.toml"), "--shard", "3/2"],
        capture_output=True, text=True, timeout=WAIT, cwd=ROOT,
    )  # fmt: skip
    assert bad_shard.returncode == 2
    assert "shard must be K/N" in bad_shard.stderr
    (tmp_path / "twins.toml").write_text(FLEET_FILE.replace('"A-1"', '"beta"'))
    twins = subprocess.run(
        [*base, "--manufacturer", "m", "--fleet", str(tmp_path / "twins.toml")],
        capture_output=True, text=True, timeout=WAIT, cwd=ROOT,
    )  # fmt: skip
    assert twins.returncode == 2
    assert "'alpha' and 'beta' are both vehicle m/beta" in twins.stderr
    empty = next(k for k in range(1, 17) if not Shard(k, 16).select(["alpha", "beta"]))
    nobody = subprocess.run(
        [*base, "--manufacturer", "m", "--fleet", str(tmp_path / "f.toml"),
         "--shard", f"{empty}/16"],
        capture_output=True, text=True, timeout=WAIT, cwd=ROOT,
    )  # fmt: skip
    assert nobody.returncode == 0
    assert f"is in shard {empty}/16: nothing to run" in nobody.stderr
    ported = subprocess.run(
        [sys.executable, "-m", "galileo_async", "--port", "sim://", "vda5050", "--broker",
         "mqtt://127.0.0.1", "--manufacturer", "m", "--fleet", str(tmp_path / "f.toml")],
        capture_output=True, text=True, timeout=WAIT, cwd=ROOT,
    )  # fmt: skip
    assert ported.returncode == 2
    assert "drop --port" in ported.stderr
