"""Patrol, mapping and charging operations against the scripted fake robot."""

from __future__ import annotations

import time
from typing import Any

import pytest

from galileo_async import (
    ChargeStatus,
    InvalidArgument,
    NotReady,
    OperationFailed,
    UnconfirmedOperation,
)
from galileo_async.protocol import (
    SaveDock,
    SaveMap,
    SetPatrolDwell,
    StartCharging,
    StartMapping,
    StartPatrol,
    Stop,
    StopCharging,
    StopMapping,
    StopPatrol,
    UpdateMap,
    encode,
)
from tests.support.scripted_robot import (
    REACTION_FRAMES,
    ScriptedRobot,
    connected,
    flush,
    ignore,
    nothing_was_sent_before_marker,
)

CLOSED: dict[str, Any] = {"nav_status": 0, "visual_status": -1}


# --- patrol ---------------------------------------------------------------------------


async def test_patrol_start_and_stop_are_confirmed() -> None:
    async with connected() as (robot, fake):
        await robot.start_patrol(timeout=2)
        assert robot.status is not None
        assert robot.status.patrolling
        await robot.stop_patrol(timeout=2)
        assert not robot.status.patrolling
        await robot.start_patrol(dwell=7, timeout=2)
    assert fake.received == [StartPatrol(), StopPatrol(), SetPatrolDwell(7)]
    assert encode(fake.received[1]) == bytes.fromhex("cdebd7 02 6d 06")  # firmware: 'm' 6


async def test_patrol_needs_navigation() -> None:
    async with connected(ScriptedRobot(**CLOSED)) as (robot, fake):
        with pytest.raises(NotReady, match="navigation") as caught:
            await robot.start_patrol()
        assert caught.value.status is not None
        with pytest.raises(NotReady):
            await robot.set_patrol_dwell(5)
        await nothing_was_sent_before_marker(robot, fake)


async def test_patrol_arguments() -> None:
    async with connected() as (robot, fake):
        with pytest.raises(InvalidArgument):
            await robot.start_patrol(dwell=256)
        with pytest.raises(InvalidArgument):
            await robot.set_patrol_dwell(-1)
        await nothing_was_sent_before_marker(robot, fake)
        await robot.set_patrol_dwell(30)
        await fake.command(SetPatrolDwell)


async def test_patrol_ignored_is_unconfirmed() -> None:
    fake = ScriptedRobot()
    fake.scripts[StartPatrol] = ignore
    async with connected(fake) as (robot, _):
        with pytest.raises(UnconfirmedOperation, match="loop_status"):
            await robot.start_patrol(timeout=0.2)


async def test_patrol_on_a_layout_without_loop_status_is_unconfirmed_at_once() -> None:
    async with connected(ScriptedRobot(layout="v1"), layout="v1") as (robot, fake):
        assert robot.status is not None
        assert robot.status.loop_status is None
        started = time.monotonic()
        with pytest.raises(UnconfirmedOperation, match="v1 status layout has no loop_status"):
            await robot.start_patrol(timeout=5)
        assert time.monotonic() - started < 1.0
        await fake.command(StartPatrol)  # it was sent, only not confirmable


# --- mapping --------------------------------------------------------------------------


async def test_mapping_start_stop_save_update() -> None:
    async with connected(ScriptedRobot(**CLOSED)) as (robot, fake):
        await robot.start_mapping(timeout=2)
        assert robot.status is not None
        assert robot.status.mapping
        await robot.save_map()
        await robot.update_map()
        await robot.stop_mapping(timeout=2)
        assert not robot.status.mapping
    assert fake.received == [StartMapping(), SaveMap(), UpdateMap(), StopMapping()]
    assert encode(fake.received[0]) == bytes.fromhex("cdebd7 02 56 00")  # 'V', not 'v'


async def test_mapping_while_navigating_is_not_ready() -> None:
    async with connected() as (robot, fake):
        with pytest.raises(NotReady, match="navigation must be closed") as caught:
            await robot.start_mapping()
        assert caught.value.status is not None
        assert caught.value.status.navigating
        await nothing_was_sent_before_marker(robot, fake)


async def test_mapping_on_a_layout_without_map_status_is_unconfirmed() -> None:
    fake = ScriptedRobot(layout="v1_charge", **CLOSED)
    async with connected(fake, layout="v1_charge") as (robot, _):
        with pytest.raises(UnconfirmedOperation, match="map_status"):
            await robot.start_mapping(timeout=5)


# --- charging -------------------------------------------------------------------------


async def test_charging_start_stop_and_dock() -> None:
    async with connected() as (robot, fake):
        state = await robot.start_charging(timeout=2)
        assert state == ChargeStatus.FINDING_DOCK
        await robot.stop_charging(timeout=2)
        await robot.save_dock()
        await flush(robot, fake)
    assert fake.received == [StartCharging(), StopCharging(), SaveDock(), Stop(100)]


async def test_charging_error_is_reported() -> None:
    async def fails(fake: ScriptedRobot, command: Any) -> None:
        await fake.frames(REACTION_FRAMES)
        fake.set(charge_status=ChargeStatus.ERROR)

    fake = ScriptedRobot()
    fake.scripts[StartCharging] = fails
    async with connected(fake) as (robot, _):
        with pytest.raises(OperationFailed) as caught:
            await robot.start_charging(timeout=2)
    assert caught.value.status is not None
    assert caught.value.status.charge_status == ChargeStatus.ERROR


async def test_charging_on_a_layout_without_charge_status_is_unconfirmed() -> None:
    async with connected(ScriptedRobot(layout="v1"), layout="v1") as (robot, _):
        with pytest.raises(UnconfirmedOperation, match="charge_status"):
            await robot.start_charging(timeout=5)
