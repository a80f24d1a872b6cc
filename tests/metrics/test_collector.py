"""Metrics against simulated robots and fleets on the virtual clock: each metric's value."""

from __future__ import annotations

import asyncio
import math

import pytest

import galileo_async as galileo
from galileo_async.battery import battery_charge
from galileo_async.fleet import Fleet
from galileo_async.metrics import GOAL_ENDINGS, ODOMETER_JUMP, Metrics
from galileo_async.models import ChargeStatus, LinkState
from galileo_async.robot import Robot
from galileo_async.sim import Simulator
from galileo_async.testing import simulated_fleet, simulated_robot
from tests.support.metrics_support import free_port, sample, samples


def state(metrics: Metrics, name: str, value: str) -> float | None:
    """galileo_link_state of robot ``name`` for state ``value`` (1 when it is the state)."""
    return sample(metrics, "galileo_link_state", robot=name, galileo_link_state=value)


def endings(metrics: Metrics, name: str) -> dict[str, float | None]:
    """galileo_goals_ended_total of robot ``name`` by ending."""
    return {
        ending: sample(metrics, "galileo_goals_ended_total", robot=name, ending=ending)
        for ending in GOAL_ENDINGS.values()
    }


async def test_a_robots_link_frames_battery_and_commands() -> None:
    async with simulated_robot() as (robot, device):
        metrics = Metrics()
        metrics.add_robot(robot, name="r1")
        try:
            device.set(power=24.0)
            await device.advance(1.0)
            assert state(metrics, "r1", "up") == 1
            for other in ("connecting", "stale", "lost", "closed"):
                assert state(metrics, "r1", other) == 0
            assert sample(metrics, "galileo_link_connected", robot="r1") == 1
            frames = sample(metrics, "galileo_frames_received_total", robot="r1")
            assert frames == robot.link.frames >= 30
            assert sample(metrics, "galileo_frames_lost_total", robot="r1") == 0
            assert sample(metrics, "galileo_battery_volts", robot="r1") == 24.0
            assert sample(metrics, "galileo_battery_percent", robot="r1") == battery_charge(24.0)
            assert sample(metrics, "galileo_last_frame_age_seconds", robot="r1") is not None
            await robot.goto(1)
            sent = sample(metrics, "galileo_commands_sent_total", robot="r1")
            assert sent == robot.link.commands_sent >= 1
        finally:
            metrics.close()


async def test_superseded_commands_are_counted() -> None:
    async with simulated_robot() as (robot, _device):
        metrics = Metrics()
        metrics.add_robot(robot, name="r1")
        try:
            async with robot.drive(0.1) as session:
                # In one loop turn: the second speed replaces the first before it is written.
                session.set(linear=0.2)
                session.set(linear=0.3)
            superseded = sample(metrics, "galileo_commands_superseded_total", robot="r1")
            assert superseded == robot.link.commands_superseded >= 2
        finally:
            metrics.close()


async def test_a_goal_a_stop_withdraws_before_it_reaches_the_link_is_not_counted() -> None:
    async with simulated_robot() as (robot, device):
        device.busy(2.0)  # the goal waits for busy_status 0: a stop withdraws it unwritten
        await device.advance(0.1)
        before = robot.link.commands_superseded
        goal = asyncio.ensure_future(robot.goto(1))
        await device.advance(0.2)
        await robot.stop()
        with pytest.raises(galileo.GalileoError):
            await goal
        # Withdrawn before it was queued on the link: not a link's superseded command.
        assert robot.link.commands_superseded == before


async def test_goal_endings_by_kind() -> None:
    async with simulated_robot() as (robot, device):
        metrics = Metrics()
        metrics.add_robot(robot, name="r1")
        try:
            assert endings(metrics, "r1") == dict.fromkeys(GOAL_ENDINGS.values(), 0)
            await robot.goto(1)
            device.abort_next_goal()
            with pytest.raises(galileo.GoalAborted):
                await robot.goto(2)
            device.reject_next_goal()
            with pytest.raises(galileo.GoalRejected):
                await robot.goto(3)
            assert endings(metrics, "r1") == {
                "reached": 1, "aborted": 1, "rejected": 1, "cancelled": 0, "stalled": 0
            }  # fmt: skip
        finally:
            metrics.close()


async def test_a_stalled_goal_counts_as_stalled() -> None:
    async with simulated_robot(progress_timeout=5.0) as (robot, device):
        metrics = Metrics()
        metrics.add_robot(robot, name="r1")
        try:
            goal = asyncio.ensure_future(robot.goto(4))
            await device.advance(1.0)  # accepted and driving
            device.freeze()
            with pytest.raises(galileo.GoalStalled):
                await goal
            assert endings(metrics, "r1")["stalled"] == 1
        finally:
            metrics.close()


async def test_stale_and_lost_links() -> None:
    async with simulated_robot(stale_timeout=1.0) as (robot, device):
        metrics = Metrics()
        metrics.add_robot(robot, name="r1")
        try:
            device.mute()
            await device.advance(1.5)
            assert state(metrics, "r1", "stale") == 1
            assert sample(metrics, "galileo_link_stale_total", robot="r1") == 1
            device.unmute()
            await robot.wait_link(LinkState.UP, timeout=5)
            device.drop_link()
            await device.advance(1.0)
            assert robot.link_state is LinkState.LOST
            assert state(metrics, "r1", "lost") == 1
            assert sample(metrics, "galileo_link_lost_total", robot="r1") == 1
            assert sample(metrics, "galileo_link_stale_total", robot="r1") == 1
            device.restore_link()
            await robot.wait_link(LinkState.UP, timeout=30)
            assert sample(metrics, "galileo_link_lost_total", robot="r1") == 1
        finally:
            metrics.close()


async def test_the_odometer_sums_a_drive_and_leaves_out_a_relocalisation() -> None:
    async with simulated_robot() as (robot, device):
        metrics = Metrics()
        metrics.add_robot(robot, name="r1")
        try:
            await device.advance(0.5)
            start = device.pose
            await robot.goto(1)
            end = device.pose
            straight = math.hypot(end.x - start.x, end.y - start.y)
            driven = sample(metrics, "galileo_odometer_meters_total", robot="r1")
            assert driven is not None
            assert straight > 1.0
            # At least the straight line (less one step not yet counted), and no detour.
            assert straight - 0.06 <= driven <= straight * 1.5
            assert metrics.odometer("r1") == driven
            await device.advance(5.0)  # standing still: nothing added
            assert sample(metrics, "galileo_odometer_meters_total", robot="r1") == driven
            device.place(end.x + 3 * ODOMETER_JUMP, end.y)  # relocalised far away
            await device.advance(1.0)
            assert sample(metrics, "galileo_odometer_meters_total", robot="r1") == driven
        finally:
            metrics.close()


async def test_charge_cycles_count_charging_starts() -> None:
    async with simulated_robot() as (robot, device):
        metrics = Metrics()
        metrics.add_robot(robot, name="r1")
        try:
            device.go_charge()
            await robot.wait_until(lambda s: s.charge_status is ChargeStatus.CHARGING, timeout=600)
            assert sample(metrics, "galileo_charge_cycles_total", robot="r1") == 1
            # Full, then trickle charging again: the same cycle.
            device.set(charge_status=ChargeStatus.CHARGED)
            await device.advance(0.5)
            device.set(charge_status=ChargeStatus.CHARGING)
            await device.advance(0.5)
            assert sample(metrics, "galileo_charge_cycles_total", robot="r1") == 1
            device.set(charge_status=ChargeStatus.FREE)  # off the dock, then on again
            await device.advance(0.5)
            device.set(charge_status=ChargeStatus.CHARGING)
            await device.advance(0.5)
            assert sample(metrics, "galileo_charge_cycles_total", robot="r1") == 2
        finally:
            metrics.close()


async def test_removal_takes_the_listeners_and_the_series_away() -> None:
    async with simulated_robot() as (robot, device):
        metrics = Metrics()
        metrics.add_robot(robot, name="r1")
        with pytest.raises(galileo.InvalidArgument, match="already"):
            metrics.add_robot(robot, name="r1")
        metrics.remove_robot("r1")
        assert samples(metrics) == {}
        assert metrics.names == ()
        metrics.add_robot(robot, name="r1")  # again, from zero
        await device.advance(0.5)
        assert sample(metrics, "galileo_odometer_meters_total", robot="r1") == 0
        metrics.close()
        assert samples(metrics) == {}


async def test_a_closed_robot_shows_closed_until_removed() -> None:
    async with simulated_robot() as (robot, _device):
        metrics = Metrics()
        metrics.add_robot(robot, name="r1")
        await robot.close()
        assert state(metrics, "r1", "closed") == 1
        assert sample(metrics, "galileo_link_connected", robot="r1") == 0
        metrics.close()


async def test_a_fleet_by_its_names() -> None:
    poses = {"robot2": {"start_pose": (1.0, 0.0, 0.0)}}
    async with simulated_fleet(3, robot_sim_options=poses) as (fleet, devices):
        metrics = Metrics()
        metrics.add_fleet(fleet)
        try:
            assert metrics.names == ("robot1", "robot2", "robot3")
            with pytest.raises(galileo.InvalidArgument):
                metrics.add_fleet(fleet)
            with pytest.raises(galileo.InvalidArgument):
                metrics.add_robot(fleet["robot1"], name="robot1")
            await fleet["robot2"].goto(4)
            devices["robot3"].drop_link()
            await devices["robot3"].advance(2)
            for name in fleet:
                assert sample(metrics, "galileo_frames_received_total", robot=name) == (
                    fleet[name].link.frames
                )
            assert sample(metrics, "galileo_link_lost_total", robot="robot3") == 1
            assert sample(metrics, "galileo_link_lost_total", robot="robot1") == 0
            assert endings(metrics, "robot2")["reached"] == 1
            assert endings(metrics, "robot1")["reached"] == 0
            driven = sample(metrics, "galileo_odometer_meters_total", robot="robot2")
            assert driven is not None
            assert driven > 1.0
            metrics.remove_fleet(fleet)
            assert samples(metrics) == {}
        finally:
            metrics.close()


async def test_a_fleet_robot_that_connects_later_is_followed_from_then() -> None:
    # Real clock: the late robot is a simulator served on a loopback port that opens later.
    port = free_port()
    ports = {"early": "sim://?speed=20", "late": f"socket://127.0.0.1:{port}"}
    async with galileo.connect_fleet(ports, retry_initial=0.05, retry_max=0.2) as fleet:
        metrics = Metrics()
        joined: list[str] = []
        fleet.add_connect_listener(lambda name, _robot: joined.append(name))
        metrics.add_fleet(fleet)
        try:
            assert metrics.names == ("early", "late")
            assert state(metrics, "late", "lost") == 1  # tried once, not connected
            assert sample(metrics, "galileo_frames_received_total", robot="late") is None
            async with Simulator(speed=20) as sim:
                await sim.serve_tcp(port=port)
                late = await until_connected(fleet, "late")
                assert joined == ["late"]
                await late.wait_until(lambda _s: late.link.frames >= 10, timeout=10)
                frames = sample(metrics, "galileo_frames_received_total", robot="late")
                assert frames is not None
                assert frames >= 10
                assert state(metrics, "late", "up") == 1
                await fleet.close()
        finally:
            metrics.close()


async def until_connected(fleet: Fleet, name: str) -> Robot:
    """Robot ``name`` of ``fleet`` once it connected (bounded, real time)."""
    async with asyncio.timeout(20):
        while (robot := fleet.get(name)) is None:  # noqa: ASYNC110 - no event to wait on
            await asyncio.sleep(0.05)
    return robot
