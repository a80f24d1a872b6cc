"""The VDA 5050 vehicle when links fail: the robot's, the broker's, the process; TLS; stopping."""

from __future__ import annotations

import asyncio
import contextlib
import os
import signal
import sys
from collections.abc import Awaitable, Callable
from pathlib import Path
from typing import Any

import anyio
import pytest

import galileo_async as galileo
from galileo_async.errors import InvalidArgument
from galileo_async.sim import Simulator
from galileo_async.vda5050 import Vehicle, VehicleConfig, run_vehicles
from galileo_async.vda5050.report import driving
from tests.support.ports import refused_port
from tests.support.ros_support import stop_process
from tests.support.vda5050_support import (
    WAIT,
    Broker,
    Master,
    broker_fixture,  # noqa: F401 (the broker fixture)
    error_types,
    node,
)
from tests.vda5050.test_vda5050_vehicle import FAST_SIM, action_status, driven_vehicle, vehicle_on

ROOT = Path(__file__).resolve().parents[2]


async def test_robot_link_lost_is_fatal_fails_the_order_and_clears_on_reconnection(
    broker: Broker,
) -> None:
    first = Simulator(speed=3)
    server = await first.serve_tcp()
    port = server.sockets[0].getsockname()[1]
    url = f"socket://127.0.0.1:{port}"
    try:
        async with (
            Master.connected(broker) as master,
            galileo.connect(url, map_targets=6, reconnect_initial=0.05, reconnect_max=0.2) as robot,
            vehicle_on(broker, robot),
        ):
            await robot.start_navigation()
            await master.order("o1", [node("start", 0.0, 0.0), node("far", 4.0, 3.0)])
            await master.next_state(lambda s: s["driving"])
            await first.close()  # the robot is gone: unplugged, or its process killed
            lost = await master.next_state(lambda s: "robotLinkLost" in error_types(s))
            [fatal] = [e for e in lost["errors"] if e["errorType"] == "robotLinkLost"]
            assert fatal["errorLevel"] == "FATAL"
            failed = lost
            if lost["nodeStates"]:
                failed = await master.next_state(lambda s: not s["nodeStates"], since=lost)
            assert failed["orderId"] == "o1"
            assert failed["lastNodeId"] == "start"
            async with Simulator(speed=3) as second:
                await second.serve_tcp(port=port)
                back = await master.next_state(lambda s: "robotLinkLost" not in error_types(s))
                # A fresh robot: navigation is closed.
                await master.next_state(lambda s: s["operatingMode"] == "MANUAL", since=back)
    finally:
        await first.close()


async def test_broker_lost_reconnects_with_back_off(broker: Broker) -> None:
    async with galileo.connect(FAST_SIM) as robot:
        options = {"reconnect_initial": 0.05, "reconnect_max": 0.2}
        async with vehicle_on(broker, robot, **options) as vehicle:
            async with Master.connected(broker) as master:
                await master.wait_for("connection", lambda m: m["connectionState"] == "ONLINE")
            await broker.stop()
            await vehicle.wait_offline()
            await anyio.sleep(0.5)  # a few reconnection attempts fail meanwhile
            await broker.start()
            async with Master.connected(broker) as master:
                online = await master.wait_for(
                    "connection", lambda m: m["connectionState"] == "ONLINE"
                )
                assert online["headerId"] >= 1  # the second ONLINE of this vehicle
                await master.instant(("s", "stateRequest"))
                await master.next_state(lambda s: action_status(s, "s") == "FINISHED")


async def test_order_running_without_broker_too_long_stops_the_robot(broker: Broker) -> None:
    async with driven_vehicle(
        broker, "sim://?speed=1", broker_loss_stop_delay=0.3, reconnect_initial=0.05,
        reconnect_max=0.2,
    ) as (robot, vehicle, master):  # fmt: skip
        await master.order("o1", [node("start", 0.0, 0.0), node("far", 4.0, 3.0)])
        await master.next_state(lambda s: s["driving"])
        await broker.stop()
        # The order is deleted once the robot stands (§6.6.3, as cancelOrder does).
        await robot.wait_until(lambda s: not s.goal_active and not driving(s), timeout=WAIT)
        await broker.start()
        assert not vehicle.progress.active
        async with Master.connected(broker) as again:
            state = await again.wait_for("state", lambda s: "brokerLost" in error_types(s))
            assert state["nodeStates"] == []
            assert state["orderId"] == "o1"


async def test_mqtts_with_a_self_signed_certificate(tmp_path: Path) -> None:
    async with (
        Broker.running(tmp_path, tls=True) as broker,
        Master.connected(broker) as master,
        galileo.connect(FAST_SIM) as robot,
        vehicle_on(broker, robot, tls_ca_file=str(broker.cert)),
    ):
        assert broker.url.startswith("mqtts://")
        await master.wait_for("connection", lambda m: m["connectionState"] == "ONLINE")
        await master.wait_for("state", lambda s: s["serialNumber"] == "r1")


async def test_many_vehicles_on_one_loop_each_with_its_own_session(broker: Broker) -> None:
    serials = ["v0", "v1", "v2"]
    async with (
        galileo.connect(FAST_SIM) as a, galileo.connect(FAST_SIM) as b,
        galileo.connect(FAST_SIM) as c, anyio.create_task_group() as group,
    ):  # fmt: skip
        vehicles = [
            Vehicle(robot, VehicleConfig(broker=broker.url, manufacturer="acme", serial_number=s))
            for robot, s in zip((a, b, c), serials, strict=True)
        ]
        group.start_soon(run_vehicles, vehicles)
        for serial in serials:
            async with Master.connected(broker, serial=serial) as master:
                await master.wait_for("connection", lambda m: m["connectionState"] == "ONLINE")
        group.cancel_scope.cancel()


# --- stopping ----------------------------------------------------------------------------


async def _stop_with_anyio_deadline(
    run: Callable[[], Awaitable[None]], online: anyio.Event
) -> None:
    with anyio.move_on_after(WAIT) as scope:
        async with anyio.create_task_group() as group:
            group.start_soon(run)
            await online.wait()
            scope.deadline = anyio.current_time()
    assert scope.cancelled_caught


async def _stop_with_fail_after(run: Callable[[], Awaitable[None]], online: anyio.Event) -> None:
    async def body() -> None:
        with anyio.fail_after(WAIT) as scope:
            async with anyio.create_task_group() as group:
                group.start_soon(run)
                await online.wait()
                scope.deadline = anyio.current_time()

    with pytest.raises(TimeoutError):
        await body()


async def _stop_with_asyncio_timeout(
    run: Callable[[], Awaitable[None]], online: anyio.Event
) -> None:
    if sys.version_info < (3, 11):
        pytest.skip("asyncio.timeout needs Python 3.11")

    async def body() -> None:
        async with asyncio.timeout(WAIT) as limit:
            task = asyncio.ensure_future(run())
            try:
                await online.wait()
                limit.reschedule(asyncio.get_running_loop().time())
                await task
            finally:
                task.cancel()
                await asyncio.gather(task, return_exceptions=True)

    with pytest.raises(TimeoutError):
        await body()


async def _stop_with_task_cancel(run: Callable[[], Awaitable[None]], online: anyio.Event) -> None:
    task = asyncio.ensure_future(run())
    await online.wait()
    task.cancel()
    with pytest.raises(asyncio.CancelledError):
        await task


async def _stop_with_failing_sibling(
    run: Callable[[], Awaitable[None]], online: anyio.Event
) -> None:
    async def sibling() -> None:
        await online.wait()
        raise RuntimeError("sibling failed")

    async def body() -> None:
        async with anyio.create_task_group() as group:
            group.start_soon(run)
            group.start_soon(sibling)

    with pytest.raises(Exception, match="unhandled errors") as caught:
        await body()
    assert caught.group_contains(RuntimeError)


@pytest.mark.parametrize(
    "stop",
    [_stop_with_anyio_deadline, _stop_with_fail_after, _stop_with_asyncio_timeout,
     _stop_with_task_cancel, _stop_with_failing_sibling],
    ids=["move_on_after", "fail_after", "asyncio.timeout", "task.cancel", "failing sibling"],
)  # fmt: skip
async def test_a_stopped_vehicle_says_offline_and_leaves_nothing_running(
    broker: Broker, stop: Callable[[Callable[[], Awaitable[None]], anyio.Event], Awaitable[None]]
) -> None:
    async with Master.connected(broker) as master, galileo.connect(FAST_SIM) as robot:
        config = VehicleConfig(broker=broker.url, manufacturer="acme", serial_number="r1")
        vehicle = Vehicle(robot, config)
        online = anyio.Event()

        async def watch() -> None:
            await master.wait_for("connection", lambda m: m["connectionState"] == "ONLINE")
            online.set()

        async with anyio.create_task_group() as group:
            group.start_soon(watch)
            await stop(vehicle.run, online)
        offline = await master.wait_for("connection", lambda m: m["connectionState"] == "OFFLINE")
        assert offline is master.received["connection"][-1]
        assert not vehicle.connected


# --- the command in its own process --------------------------------------------------------


async def _start_cli(broker: Broker, serial: str, tmp_path: Path) -> asyncio.subprocess.Process:
    log = (tmp_path / f"cli-{serial}.log").open("ab")
    try:
        return await asyncio.create_subprocess_exec(
            sys.executable, "-m", "galileo_async", "--port", FAST_SIM, "vda5050",
            "--broker", broker.url, "--manufacturer", "acme", "--serial-number", serial,
            "--start-navigation",
            stdin=asyncio.subprocess.DEVNULL, stdout=log, stderr=log, cwd=ROOT,
        )  # fmt: skip
    finally:
        log.close()


async def test_cli_killed_leaves_its_last_will(broker: Broker, tmp_path: Path) -> None:
    async with Master.connected(broker, serial="p1") as master:
        proc = await _start_cli(broker, "p1", tmp_path)
        try:
            await master.wait_for("connection", lambda m: m["connectionState"] == "ONLINE")
            await master.wait_for("state", lambda s: s["operatingMode"] == "AUTOMATIC")
            os.kill(proc.pid, signal.SIGKILL)
            will = await master.wait_for(
                "connection", lambda m: m["connectionState"] == "CONNECTIONBROKEN"
            )
            assert will["serialNumber"] == "p1"
        finally:
            await stop_process(proc)


async def test_cli_ctrl_c_says_offline_and_exits_0(broker: Broker, tmp_path: Path) -> None:
    async with Master.connected(broker, serial="p2") as master:
        proc = await _start_cli(broker, "p2", tmp_path)
        try:
            await master.wait_for("connection", lambda m: m["connectionState"] == "ONLINE")
            proc.send_signal(signal.SIGINT)
            with anyio.fail_after(WAIT):
                code = await proc.wait()
            log = (tmp_path / "cli-p2.log").read_text()
            assert code == 0, log
            await master.wait_for("connection", lambda m: m["connectionState"] == "OFFLINE")
            assert master.received["connection"][-1]["connectionState"] == "OFFLINE"
        finally:
            await stop_process(proc)


async def test_cli_says_when_it_is_connected_and_when_the_robot_link_goes_and_returns(
    broker: Broker, tmp_path: Path
) -> None:
    first = Simulator(speed=3)
    server = await first.serve_tcp()
    port = server.sockets[0].getsockname()[1]
    log_path = tmp_path / "cli-p3.log"
    try:
        async with Master.connected(broker, serial="p3") as master:
            with log_path.open("ab") as log:
                proc = await asyncio.create_subprocess_exec(
                    sys.executable, "-m", "galileo_async", "--port",
                    f"socket://127.0.0.1:{port}", "vda5050", "--broker", broker.url,
                    "--manufacturer", "acme", "--serial-number", "p3",
                    stdin=asyncio.subprocess.DEVNULL, stdout=log, stderr=log, cwd=ROOT,
                )  # fmt: skip
            try:
                await master.wait_for("connection", lambda m: m["connectionState"] == "ONLINE")
                await first.close()  # the robot restarts
                await master.wait_for("state", lambda s: "robotLinkLost" in error_types(s))
                async with Simulator(speed=3) as second:
                    await second.serve_tcp(port=port)
                    await master.next_state(lambda s: "robotLinkLost" not in error_types(s))
                    proc.send_signal(signal.SIGINT)
                    with anyio.fail_after(WAIT):
                        code = await proc.wait()
            finally:
                await stop_process(proc)
    finally:
        await first.close()
    text = log_path.read_text()
    assert code == 0, text
    lines = text.splitlines()
    connected = [line for line in lines if line.startswith("connected to mqtt://")]
    assert len(connected) == 1, text
    assert lines.index(connected[0]) > next(
        i for i, line in enumerate(lines) if line.startswith("connecting to")
    )
    down = [line for line in lines if line.startswith(("robot link LOST", "robot link STALE"))]
    assert down, text
    assert lines.index(down[0]) < lines.index("robot link UP again"), text


async def test_the_example_drives_two_vehicles(broker: Broker) -> None:
    proc = await asyncio.create_subprocess_exec(
        sys.executable, str(ROOT / "examples" / "vda5050_vehicle.py"), broker.url,
        stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.STDOUT,
        env={**os.environ, "GALILEO_PORT": "sim://?speed=20"},
    )  # fmt: skip
    try:
        with anyio.fail_after(60):
            out, _ = await proc.communicate()
    finally:
        await stop_process(proc)
    text = out.decode()
    assert proc.returncode == 0, text
    assert "robot-0: order to-1.0,1.0 done at (1.00, 1.00)" in text
    assert "robot-1: order to--1.0,2.0 done at (-1.00, 2.00)" in text
    assert "all vehicles offline" in text


async def test_stopped_while_connecting_or_backing_off(broker: Broker) -> None:
    async with galileo.connect(FAST_SIM) as robot:
        config = VehicleConfig(broker=broker.url, manufacturer="acme", serial_number="r1")
        task = asyncio.ensure_future(Vehicle(robot, config).run())
        await asyncio.sleep(0)  # the session has begun to connect
        task.cancel()
        with pytest.raises(asyncio.CancelledError):
            await task
        with anyio.move_on_after(0):
            await Vehicle(robot, config).run()
        with refused_port() as port:
            unreachable = VehicleConfig(
                broker=f"mqtt://127.0.0.1:{port}", manufacturer="acme", serial_number="r2",
                reconnect_initial=0.01, reconnect_max=0.02,
            )  # fmt: skip
            vehicle = Vehicle(robot, unreachable)
            with anyio.move_on_after(0.3):  # a few refused attempts and back-off sleeps
                await vehicle.run()
        assert not vehicle.connected
    async with Master.connected(broker) as master:
        last = await master.wait_for("connection", lambda m: True)
        assert last["connectionState"] == "OFFLINE"


def test_a_vehicle_needs_a_config() -> None:
    with pytest.raises(InvalidArgument):
        Vehicle(None, {"broker": "mqtt://127.0.0.1"})  # type: ignore[arg-type]


class FreezingProxy:
    """A TCP relay to the simulator that can stop relaying without closing: a stale link."""

    def __init__(self, target_port: int) -> None:
        self.target_port = target_port
        self.frozen = False
        self.server: asyncio.Server | None = None
        self.writers: list[asyncio.StreamWriter] = []
        self.relays: list[asyncio.Task[None]] = []
        self.accepted = 0
        self._accept_event = asyncio.Event()

    async def wait_accepted(self, count: int) -> None:
        """Wait until ``count`` host connections have been accepted in all."""
        with anyio.fail_after(WAIT):
            while self.accepted < count:
                self._accept_event.clear()
                await self._accept_event.wait()

    async def start(self) -> int:
        self.server = await asyncio.start_server(self._accept, "127.0.0.1", 0)
        return int(self.server.sockets[0].getsockname()[1])

    def _accept(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        self.accepted += 1
        self._accept_event.set()
        self.writers.append(writer)
        self.relays.append(asyncio.ensure_future(self._relay(reader, writer)))

    async def _relay(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        up_reader, up_writer = await asyncio.open_connection("127.0.0.1", self.target_port)
        self.writers.append(up_writer)

        async def pump(source: asyncio.StreamReader, sink: asyncio.StreamWriter) -> None:
            with contextlib.suppress(OSError):
                while data := await source.read(4096):
                    if not self.frozen:
                        sink.write(data)
            sink.close()

        async with anyio.create_task_group() as group:
            group.start_soon(pump, reader, up_writer)
            group.start_soon(pump, up_reader, writer)

    async def close(self) -> None:
        if self.server is not None:
            self.server.close()
            await self.server.wait_closed()
        for writer in self.writers:
            writer.close()
        await asyncio.gather(*self.relays, return_exceptions=True)


async def test_a_stale_robot_link_is_fatal_until_frames_come_again(broker: Broker) -> None:
    async with Simulator(speed=3) as sim:
        server = await sim.serve_tcp()
        proxy = FreezingProxy(server.sockets[0].getsockname()[1])
        url = f"socket://127.0.0.1:{await proxy.start()}"
        try:
            async with (
                Master.connected(broker) as master,
                galileo.connect(
                    url, map_targets=6, stale_timeout=0.3, stale_reconnect=None
                ) as robot,
                vehicle_on(broker, robot),
            ):
                await robot.start_navigation()
                await master.order("o1", [node("start", 0.0, 0.0), node("far", 4.0, 3.0)])
                await master.next_state(lambda s: s["driving"])
                proxy.frozen = True  # the robot process hangs: the socket stays open
                stale = await master.next_state(lambda s: "robotLinkLost" in error_types(s))
                [fatal] = [e for e in stale["errors"] if e["errorType"] == "robotLinkLost"]
                assert fatal["errorLevel"] == "FATAL"
                assert {"referenceKey": "link", "referenceValue": "LinkStale"} in (
                    fatal["errorReferences"]
                )
                proxy.frozen = False
                back = await master.next_state(lambda s: "robotLinkLost" not in error_types(s))
                assert back["nodeStates"] == []  # the order failed and stays failed
                assert back["orderId"] == "o1"
        finally:
            await proxy.close()


async def test_a_dead_node_behind_a_port_that_reopens_is_one_outage(broker: Broker) -> None:
    async with Simulator(speed=3) as sim:
        server = await sim.serve_tcp()
        proxy = FreezingProxy(server.sockets[0].getsockname()[1])
        url = f"socket://127.0.0.1:{await proxy.start()}"
        options: dict[str, Any] = {
            "stale_timeout": 0.1, "stale_reconnect": 2.0,
            "reconnect_initial": 0.02, "reconnect_max": 0.1,
        }  # fmt: skip
        try:
            async with (
                Master.connected(broker) as master,
                galileo.connect(url, map_targets=6, **options) as robot,
                vehicle_on(broker, robot),
            ):
                events = robot.events()
                proxy.frozen = True  # the node dies; every reopen is accepted, then silent
                lost = await master.next_state(lambda s: "robotLinkLost" in error_types(s))
                await proxy.wait_accepted(5)
                proxy.frozen = False
                back = await master.next_state(lambda s: "robotLinkLost" not in error_types(s))
                states = master.received["state"]
                outage = states[states.index(lost) : states.index(back)]
                assert all("robotLinkLost" in error_types(state) for state in outage)
                seen: list[str] = []
                with anyio.fail_after(WAIT):
                    async for event in events:
                        if event.name in LINK_EVENTS:
                            seen.append(event.name)
                        if event.name == "ConnectionRestored":
                            break
                assert seen == ["LinkStale", "ConnectionLost", "ConnectionRestored"]
        finally:
            await proxy.close()


LINK_EVENTS = {"LinkStale", "LinkRestored", "ConnectionLost", "ConnectionRestored"}


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--broker", "http://127.0.0.1"], "mqtt:// or mqtts://"),
        (["--broker", "mqtt://127.0.0.1", "--visualization-rate", "60"], "at most 30"),
        (["--broker", "mqtt://127.0.0.1", "--interface-name", "a/b"], "interface_name"),
        (["--broker", "mqtt://127.0.0.1", "--vda-version", "3.0"], "vda_version"),
        (["--broker", "mqtt://127.0.0.1", "--width", "-1"], "width"),
    ],
)
def test_cli_refuses_bad_options_before_connecting(args: list[str], message: str) -> None:
    from tests.cli.test_cli import invoke

    common = ["--manufacturer", "acme", "--serial-number", "r1"]
    result = invoke("vda5050", *args, *common, port="/dev/nonexistent-galileo")
    assert result.exit_code == 2, result.output
    assert message in result.output


def test_cli_help_lists_the_vda5050_command() -> None:
    from tests.cli.test_cli import invoke

    result = invoke("--help", port=None)
    assert " vda5050 " in result.stdout


async def test_a_clean_stop_cancels_the_goal_in_progress(broker: Broker) -> None:
    async with Master.connected(broker) as master, galileo.connect("sim://?speed=2") as robot:
        async with vehicle_on(broker, robot):
            await robot.start_navigation()
            await master.order("o1", [node("start", 0.0, 0.0), node("far", 4.0, 3.0)])
            await master.wait_for("state", lambda s: s["driving"])
        status = await robot.wait_until(lambda s: not s.goal_active, timeout=WAIT)
        assert status.pose is not None
        assert abs(status.pose.x - 4.0) > 0.5  # stopped on the way, not arrived
        await master.wait_for("connection", lambda m: m["connectionState"] == "OFFLINE")
