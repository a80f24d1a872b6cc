"""The VDA 5050 vehicle stopped (SIGTERM, SIGHUP, Ctrl-C, a cancelled run()): a clean goodbye.

The running order is cancelled as cancelOrder cancels it (VDA 5050 §6.6.3): the robot stops,
every action not yet finished is FAILED; then a last state, then OFFLINE (not the last will).
"""

from __future__ import annotations

import asyncio
import contextlib
import signal
import sys
from collections.abc import AsyncIterator, Callable
from pathlib import Path
from typing import Any

import anyio
import pytest

import galileo_async as galileo
from galileo_async.protocol import Cancel, Command, Goto, StartCharging, Stop, StopCharging
from galileo_async.sim import SimState, Simulator
from galileo_async.vda5050 import Vehicle, VehicleConfig
from tests.support.ros_support import stop_process
from tests.support.vda5050_support import (
    Broker,
    Master,
    broker_fixture,  # noqa: F401 (the broker fixture)
    error_types,
    node,
)
from tests.vda5050.test_vda5050_vehicle import FAST_SIM, driven_vehicle

ROOT = Path(__file__).resolve().parents[2]
#: Bound on a process's exit or the robot's stop (generous: a loaded machine), seconds.
EXIT_WAIT = 60.0


class ServedRobot:
    """A simulated robot on 127.0.0.1 (this test's loop), with every command it took."""

    def __init__(self, simulator: Simulator, url: str) -> None:
        self.simulator = simulator
        self.url = url
        self.commands: list[type[Command]] = []
        simulator.on_command(lambda command: self.commands.append(type(command)))

    @property
    def state(self) -> SimState:
        return self.simulator.state

    def after(self, kind: type[Command]) -> list[type[Command]]:
        assert kind in self.commands, self.commands
        return self.commands[self.commands.index(kind) + 1 :]

    async def reaches(self, predicate: Callable[[SimState], bool]) -> None:
        """Wait (bounded) until ``predicate`` holds, looking again after every frame or so."""
        with anyio.fail_after(EXIT_WAIT):
            while not predicate(self.state):  # noqa: ASYNC110 - the simulator has no notification
                await anyio.sleep(0.01)


@contextlib.asynccontextmanager
async def served_robot(**config: Any) -> AsyncIterator[ServedRobot]:
    simulator = Simulator(speed=1.0, **config)  # real time: driving takes seconds
    server = await simulator.serve_tcp()
    try:
        yield ServedRobot(simulator, f"socket://127.0.0.1:{server.sockets[0].getsockname()[1]}")
    finally:
        await simulator.close()


def moving(state: SimState) -> bool:
    status = state.status
    return abs(status.current_speed_x or 0.0) > 0.1 or abs(status.current_speed_theta or 0.0) > 0.1


def ready(state: dict[str, Any]) -> bool:
    """The vehicle takes orders: navigation open, its position known."""
    position = state.get("agvPosition") or {}
    return state["operatingMode"] == "AUTOMATIC" and bool(position.get("positionInitialized"))


def stopped(state: SimState) -> bool:
    status = state.status
    return not status.goal_active and status.current_speed_x == 0 == status.current_speed_theta


@contextlib.asynccontextmanager
async def vehicle_process(
    broker: Broker, robot: ServedRobot, serial: str, tmp_path: Path
) -> AsyncIterator[asyncio.subprocess.Process]:
    """``galileo vda5050`` for ``robot`` in its own process, once it is ONLINE and AUTOMATIC."""
    log = (tmp_path / f"cli-{serial}.log").open("ab")
    try:
        proc = await asyncio.create_subprocess_exec(
            sys.executable, "-m", "galileo_async", "--port", robot.url, "vda5050",
            "--broker", broker.url, "--manufacturer", "acme", "--serial-number", serial,
            "--start-navigation",
            stdin=asyncio.subprocess.DEVNULL, stdout=log, stderr=log, cwd=ROOT,
        )  # fmt: skip
    finally:
        log.close()
    try:
        yield proc
    finally:
        await stop_process(proc)


async def signalled(proc: asyncio.subprocess.Process, sig: signal.Signals) -> int:
    proc.send_signal(sig)
    with anyio.fail_after(EXIT_WAIT):
        return await proc.wait()


async def goodbye(master: Master) -> dict[str, Any]:
    """The vehicle's last state, once OFFLINE came; no last will was published."""
    await master.wait_for("connection", lambda m: m["connectionState"] == "OFFLINE")
    states = [m["connectionState"] for m in master.received["connection"]]
    assert states[-1] == "OFFLINE", states
    assert "CONNECTIONBROKEN" not in states, states
    return master.received["state"][-1]


SIGNALS = [signal.SIGTERM, signal.SIGHUP, signal.SIGINT]


@pytest.mark.parametrize("sig", SIGNALS, ids=[sig.name for sig in SIGNALS])
async def test_cli_stopped_mid_order_cancels_it_stops_the_robot_and_says_offline(
    broker: Broker, tmp_path: Path, sig: signal.Signals
) -> None:
    serial = f"t-{sig.name.lower()}"
    async with (
        served_robot() as robot,
        Master.connected(broker, serial=serial) as master,
        vehicle_process(broker, robot, serial, tmp_path) as proc,
    ):
        await master.wait_for("state", ready)
        await master.order("o1", [node("start", 0.0, 0.0), node("4")])  # target 4: 5 m away
        await master.next_state(lambda s: s["orderId"] == "o1" and s["driving"])
        await robot.reaches(moving)
        code = await signalled(proc, sig)
        log = (tmp_path / f"cli-{serial}.log").read_text()
        assert code == 0, log
        last = await goodbye(master)
        assert last["orderId"] == "o1"  # kept (§6.6.3), the order deleted:
        assert last["nodeStates"] == []
        assert last["edgeStates"] == []
        assert not last["driving"]
        [shutdown] = [e for e in last["errors"] if e["errorType"] == "vehicleShutdown"]
        assert shutdown["errorLevel"] == "WARNING"
        assert {"referenceKey": "orderId", "referenceValue": "o1"} in shutdown["errorReferences"]
        assert sig.name in shutdown["errorDescription"]
        assert f"stopped by {sig.name}: order o1 cancelled" in log, log
        assert "OFFLINE published" in log, log
    await robot.reaches(stopped)
    after = robot.after(Goto)
    assert Cancel in after, after
    assert Stop in after, after


async def test_cli_on_sigterm_fails_the_running_and_the_waiting_actions(
    broker: Broker, tmp_path: Path
) -> None:
    # The dock 5 m away: startCharging runs (RUNNING) for seconds while the robot drives there.
    async with (
        served_robot(dock=(-4.0, -3.0)) as robot,
        Master.connected(broker, serial="t-actions") as master,
        vehicle_process(broker, robot, "t-actions", tmp_path) as proc,
    ):
        await master.wait_for("connection", lambda m: m["connectionState"] == "ONLINE")
        await master.instant(("c1", "startCharging"), ("s1", "stateRequest"))

        def running(state: dict[str, Any]) -> bool:
            statuses = {a["actionId"]: a["actionStatus"] for a in state["actionStates"]}
            return statuses == {"c1": "RUNNING", "s1": "WAITING"}

        await master.next_state(running)
        await robot.reaches(moving)
        code = await signalled(proc, signal.SIGTERM)
        assert code == 0, (tmp_path / "cli-t-actions.log").read_text()
        last = await goodbye(master)
        actions = {a["actionId"]: a for a in last["actionStates"]}
        assert {key: a["actionStatus"] for key, a in actions.items()} == {
            "c1": "FAILED",
            "s1": "FAILED",
        }
        assert "SIGTERM" in actions["c1"]["resultDescription"]
        assert "vehicleShutdown" in error_types(last)
    await robot.reaches(lambda state: stopped(state) and not state.status.charge_status)
    assert StopCharging in robot.after(StartCharging)


async def test_a_cancelled_run_cancels_the_order_then_publishes_a_state_then_offline(
    broker: Broker,
) -> None:
    async with driven_vehicle(broker, "sim://?speed=2") as (robot, vehicle, master):
        await master.order("o1", [node("start", 0.0, 0.0), node("far", -4.0, -3.0)])
        await master.next_state(lambda s: s["orderId"] == "o1" and s["driving"])
    last = await goodbye(master)
    assert last["nodeStates"] == []
    assert "vehicleShutdown" in error_types(last)
    assert vehicle.shut_down_report is not None
    assert vehicle.shut_down_report.order_id == "o1"
    assert not robot.status or not robot.status.goal_active


async def test_shut_down_refuses_new_orders_and_says_what_it_did(broker: Broker) -> None:
    async with driven_vehicle(broker) as (_, vehicle, master):
        await master.order("o1", [node("start", 0.0, 0.0), node("far", -4.0, -3.0)])
        await master.next_state(lambda s: s["driving"])
        report = await vehicle.shut_down("maintenance")
        assert report.order_id == "o1"
        assert str(report).startswith("order o1 cancelled, robot stopped")
        assert await vehicle.shut_down("again") is report  # once
        await master.order("o2", [node("start", 0.0, 0.0), node("near", 0.5, 0.0)])
        refused = await master.next_state(lambda s: "orderError" in error_types(s))
        assert refused["orderId"] == "o1"
        assert "shutting down" in str(refused["errors"])


async def test_a_vehicle_without_a_broker_still_stops_its_robot_when_cancelled() -> None:
    async with galileo.connect(FAST_SIM) as robot:
        config = VehicleConfig(
            broker="mqtt://127.0.0.1:1", manufacturer="acme", serial_number="nobroker"
        )
        vehicle = Vehicle(robot, config)
        with anyio.move_on_after(0.5):
            await vehicle.run()
        report = vehicle.shut_down_report
        assert report is not None
        assert report.order_id is None
        assert report.stop is not None
