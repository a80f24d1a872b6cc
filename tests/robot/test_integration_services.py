"""Patrol, mapping and charging end to end against the Simulator (matrix: sim_integration)."""

from __future__ import annotations

import asyncio

import pytest

import galileo_async as galileo
from galileo_async import (
    ChargeStatus,
    GalileoStatus,
    NotReady,
    TargetStatus,
    UnconfirmedOperation,
)
from galileo_async.protocol import StartMapping
from galileo_async.sim import Simulator
from tests.support.sim_integration import (
    NEAR,
    RIGHT,
    TARGETS,
    WAIT,
    Mode,
    modes,
    near,
    robot_on_sim,
    sim_reaches,
    sim_seconds,
)

#: Real seconds an operation the robot ignores is given before it counts as unconfirmed.
SHORT = sim_seconds(8)


async def _unconfirmed_at_once(mode: Mode, field: str, operation: object) -> None:
    """Await ``operation``: UnconfirmedOperation naming ``field``, raised without waiting."""
    assert not mode.has(field)
    with pytest.raises(UnconfirmedOperation, match=f"has no {field}"):
        await operation  # type: ignore[misc]


async def _patrolling(robot: galileo.Robot, sim: Simulator, on: bool) -> None:
    """The robot shows patrol ``on`` where its layout can, and the simulator agrees."""
    if robot.status is not None and robot.status.loop_status is not None:
        assert robot.status.patrolling is on
    await sim_reaches(robot, sim, lambda s: bool(s.status.loop_status) is on)


@modes()
async def test_patrol_start_and_stop(mode: Mode) -> None:
    async with robot_on_sim(mode) as (sim, robot):
        if mode.has("loop_status"):
            await robot.start_patrol(timeout=WAIT)
        else:
            await _unconfirmed_at_once(mode, "loop_status", robot.start_patrol(timeout=WAIT))
        await _patrolling(robot, sim, True)
        # The patrol drives to the targets in id order.
        await robot.wait_until(
            lambda s: s.target_num_id == NEAR and s.target_status == TargetStatus.WORKING,
            timeout=WAIT,
        )

        if mode.real:
            # 'm' 6 stops the patrol and its goal but keeps navigation (docs/protocol.md §2.g).
            if mode.has("loop_status"):
                await robot.stop_patrol(timeout=WAIT)
            else:
                await _unconfirmed_at_once(mode, "loop_status", robot.stop_patrol())
            await _patrolling(robot, sim, False)
            await sim_reaches(robot, sim, lambda s: s.status.target_status == TargetStatus.FREE)
            assert robot.status is not None
            assert robot.status.navigating
            assert sim.state.status.nav_status == 1
        else:
            # The document's robot ignores 'm' 6; only 'm' 4 (stop navigation) ends patrol.
            with pytest.raises(UnconfirmedOperation):
                await robot.stop_patrol(timeout=SHORT)
            assert sim.state.status.loop_status == 1
            await robot.stop_navigation(timeout=WAIT)
            await _patrolling(robot, sim, False)


@modes()
async def test_patrol_with_dwell(mode: Mode) -> None:
    async with robot_on_sim(mode) as (sim, robot):
        arrived_at: list[float] = []

        def arrived_near(status: GalileoStatus) -> bool:
            if status.target_num_id == NEAR and status.target_status == TargetStatus.FREE:
                arrived_at.append(sim.state.time)
                return True
            return False

        # Both waits see every frame from before the patrol starts: under load the test may
        # resume only after the robot has arrived or left (the dwell is 25 ms of real time).
        arrival = asyncio.ensure_future(robot.wait_until(arrived_near, timeout=WAIT))
        left_at: list[float] = []

        def left_near(status: GalileoStatus) -> bool:
            if status.target_num_id == NEAR + 1:
                left_at.append(sim.state.time)
                return True
            return False

        leaving = asyncio.ensure_future(robot.wait_until(left_near, timeout=WAIT))
        await asyncio.sleep(0)  # both are registered
        if mode.real:
            # Firmware: 'm' 5 TT sets the wait and starts patrol (docs/protocol.md §2.g).
            if mode.has("loop_status"):
                await robot.start_patrol(dwell=2, timeout=WAIT)
            else:
                await _unconfirmed_at_once(mode, "loop_status", robot.start_patrol(dwell=2))
        else:
            # The document's 'm' 5 TT only sets the wait; start_patrol() then starts it.
            with pytest.raises(UnconfirmedOperation):
                await robot.start_patrol(dwell=2, timeout=SHORT)
            assert sim.state.status.loop_status == 0
            if mode.has("loop_status"):
                await robot.start_patrol(timeout=WAIT)
            else:
                await _unconfirmed_at_once(mode, "loop_status", robot.start_patrol())
        await _patrolling(robot, sim, True)
        assert sim.state.patrol_dwell == 2.0

        # It waits the dwell time at the first target before leaving for the next.
        arrived = await arrival
        left = await leaving
        if arrived.time_stamp is not None and left.time_stamp is not None:
            assert 1.9 <= (left.time_stamp - arrived.time_stamp) / 30 <= 2.1
        else:
            # No frame counter: the simulator's clock when each frame was decoded, coarse by
            # a tick and by how late a loaded machine delivers each frame (about 1 s at most).
            assert 0.5 <= left_at[0] - arrived_at[0] <= 3.5


@modes()
async def test_set_patrol_dwell(mode: Mode) -> None:
    async with robot_on_sim(mode) as (sim, robot):
        await robot.set_patrol_dwell(5)
        await sim_reaches(robot, sim, lambda s: s.patrol_dwell == 5.0)
        # Firmware: setting the wait also starts patrol (docs/protocol.md §2.g); the document: no.
        if mode.real:
            await sim_reaches(robot, sim, lambda s: s.status.loop_status == 1)
        else:
            assert sim.state.status.loop_status == 0
        await robot.stop_navigation(timeout=WAIT)
        with pytest.raises(NotReady, match="navigation must be open"):
            await robot.set_patrol_dwell(3)
        with pytest.raises(NotReady, match="navigation must be open"):
            await robot.start_patrol()


@modes()
async def test_mapping(mode: Mode) -> None:
    # Busy saving for 20 simulated s (0.25 s): long enough to be seen under load.
    async with robot_on_sim(mode, busy_on_map_stop=1.0, busy_on_save=20.0) as (sim, robot):
        with pytest.raises(NotReady, match="navigation must be closed"):
            await robot.start_mapping()
        assert sim.state.status.map_status == 0

        # Start mapping also stops navigation (docs/protocol.md §2.h).
        await robot.send(StartMapping())
        await robot.wait_until(lambda s: not s.navigating, timeout=WAIT)
        await sim_reaches(robot, sim, lambda s: s.status.map_status == 1)
        if mode.has("map_status"):
            assert robot.status is not None
            assert robot.status.mapping
            with pytest.raises(NotReady, match="building a map"):
                await robot.start_navigation()
            await robot.stop_mapping(timeout=WAIT)
            assert robot.status is not None
            assert robot.status.map_status == 0
        else:
            assert robot.status is not None
            assert robot.status.map_status is None
            # Without map_status the driver cannot see mapping: the robot ignores the start.
            with pytest.raises(UnconfirmedOperation):
                await robot.start_navigation(timeout=SHORT)
            await _unconfirmed_at_once(mode, "map_status", robot.stop_mapping())
        await sim_reaches(robot, sim, lambda s: s.status.map_status == 0)

        if mode.has("map_status"):
            await robot.start_mapping(timeout=WAIT)
        else:
            await _unconfirmed_at_once(mode, "map_status", robot.start_mapping())
        await sim_reaches(robot, sim, lambda s: s.status.map_status == 1)
        if mode.has("current_pose_x"):
            assert robot.status is not None
            assert robot.status.pose is not None

        await robot.save_map(timeout=WAIT)  # not confirmable; the robot is busy saving
        await sim_reaches(robot, sim, lambda s: s.status.busy_status == 1)
        if mode.has("map_status"):
            await robot.stop_mapping(timeout=WAIT)
        else:
            await _unconfirmed_at_once(mode, "map_status", robot.stop_mapping())
        await sim_reaches(robot, sim, lambda s: s.status.map_status == 0)

        await robot.update_map(timeout=WAIT)  # continues the map: mapping again
        await sim_reaches(robot, sim, lambda s: s.status.map_status == 1)


@modes()
async def test_charging(mode: Mode) -> None:
    async with robot_on_sim(mode, power=27.9, docking_time=1.0) as (sim, robot):
        await robot.goto(NEAR, timeout=WAIT)
        await robot.save_dock()
        await sim_reaches(robot, sim, lambda s: s.dock == TARGETS[NEAR])
        await robot.goto(RIGHT, timeout=WAIT)

        if mode.has("charge_status"):
            assert await robot.start_charging(timeout=WAIT) == ChargeStatus.FINDING_DOCK
            status = await robot.wait_until(lambda s: s.charging, timeout=WAIT)
            assert status.charge_status in (ChargeStatus.CHARGING, ChargeStatus.CHARGED)
            await robot.wait_until(lambda s: s.charge_status == ChargeStatus.CHARGED, timeout=WAIT)
        else:
            await _unconfirmed_at_once(mode, "charge_status", robot.start_charging())
            assert robot.status is not None
            assert robot.status.charge_status is None
            await sim_reaches(robot, sim, lambda s: s.status.charge_status == ChargeStatus.CHARGED)
        # It drove back to the saved dock, and the voltage every layout reports rose.
        assert near(sim.state.pose.x, TARGETS[NEAR][0], 0.01)
        await robot.wait_until(lambda s: s.power is not None and s.power >= 28.0, timeout=WAIT)

        if mode.has("charge_status"):
            await robot.stop_charging(timeout=WAIT)
            assert robot.status is not None
            assert robot.status.charge_status == ChargeStatus.FREE
        else:
            await _unconfirmed_at_once(mode, "charge_status", robot.stop_charging())
        await sim_reaches(robot, sim, lambda s: s.status.charge_status == ChargeStatus.FREE)
