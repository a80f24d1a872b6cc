"""Fleet.stop(): every robot at once, each robot's StopReport or its error."""

from __future__ import annotations

import pytest
from ports import refused_port

from galileo_async import StopReport, connect_fleet
from galileo_async.errors import InvalidArgument, NotReady
from galileo_async.protocol import Stop
from galileo_async.testing import simulated_fleet

SIM = "sim://?speed=50"


async def test_fleet_stop_stops_every_robot_at_once() -> None:
    async with simulated_fleet(3) as (fleet, devices):
        results = await fleet.stop(40)
        assert list(results) == ["robot1", "robot2", "robot3"]
        for name, result in results.items():
            assert result.ok, result.error
            assert isinstance(result.value, StopReport)
            assert devices[name].received(Stop) == [Stop(40)]


async def test_fleet_stop_checks_its_arguments_before_sending() -> None:
    async with simulated_fleet(2) as (fleet, devices):
        with pytest.raises(InvalidArgument, match="brake"):
            await fleet.stop(101)
        with pytest.raises(InvalidArgument, match="timeout"):
            await fleet.stop(timeout=-1)
        assert all(device.commands == [] for device in devices.values())


async def test_a_robot_not_connected_gets_its_error() -> None:
    with refused_port() as port:
        ports = {"a": SIM, "down": f"socket://127.0.0.1:{port}"}
        async with connect_fleet(ports, first_status_timeout=5) as fleet:
            results = await fleet.stop()
    assert results["a"].ok
    error = results["down"].error
    assert isinstance(error, NotReady)
    assert "robot 'down' is not connected" in str(error)
    assert "cannot connect" in str(error)  # why it is not
