"""Fleet.add_connect_listener: told of each robot that connects later, a broken one logged."""

from __future__ import annotations

import asyncio

import pytest

import galileo_async as galileo
from galileo_async.sim import Simulator
from tests.support.metrics_support import free_port


async def test_listeners_hear_of_a_late_robot_and_a_broken_one_is_logged(
    caplog: pytest.LogCaptureFixture,
) -> None:
    port = free_port()
    ports = {"early": "sim://?speed=20", "late": f"socket://127.0.0.1:{port}"}
    heard: list[tuple[str, galileo.Robot]] = []
    removed: list[str] = []

    def broken(_name: str, _robot: galileo.Robot) -> None:
        raise RuntimeError("listener bug")

    def gone(name: str, _robot: galileo.Robot) -> None:
        removed.append(name)

    async with galileo.connect_fleet(ports, retry_initial=0.05, retry_max=0.2) as fleet:
        fleet.add_connect_listener(broken)
        fleet.add_connect_listener(lambda name, robot: heard.append((name, robot)))
        fleet.add_connect_listener(gone)
        fleet.remove_connect_listener(gone)
        fleet.remove_connect_listener(broken)
        fleet.add_connect_listener(broken)  # after the recorder: it must not stop it
        async with Simulator(speed=20) as sim:
            await sim.serve_tcp(port=port)
            async with asyncio.timeout(20):
                while fleet.get("late") is None:  # noqa: ASYNC110 - no event to wait on
                    await asyncio.sleep(0.05)
            assert heard == [("late", fleet["late"])]  # not "early": it was there before
            assert removed == []
            assert "connect listener" in caplog.text
            await fleet.close()


async def test_connected_true_also_tells_of_the_robots_connected_now() -> None:
    port = free_port()
    ports = {"early": "sim://?speed=20", "late": f"socket://127.0.0.1:{port}"}
    heard: list[str] = []
    async with galileo.connect_fleet(ports, retry_initial=0.05, retry_max=0.2) as fleet:
        fleet.add_connect_listener(lambda name, _robot: heard.append(name), connected=True)
        assert heard == ["early"]
        async with Simulator(speed=20) as sim:
            await sim.serve_tcp(port=port)
            async with asyncio.timeout(20):
                while fleet.get("late") is None:  # noqa: ASYNC110 - no event to wait on
                    await asyncio.sleep(0.05)
            assert heard == ["early", "late"]  # each once
            await fleet.close()
