"""Goals end to end: a Robot against the Simulator over TCP and a pty (matrix: sim_integration)."""

from __future__ import annotations

import asyncio
import math
import struct

import anyio
import pytest

import galileo_async as galileo
from galileo_async import (
    AcceptTimeout,
    GoalAborted,
    GoalCancelled,
    GoalRejected,
    NotReady,
    OperationTimeout,
    TargetStatus,
)
from galileo_async.protocol import Goto
from galileo_async.sim import SimState, Simulator
from tests.support.sim_integration import (
    FAR,
    INVALID_ID,
    MAP_TARGETS,
    NEAR,
    RIGHT,
    TARGETS,
    WAIT,
    Mode,
    modes,
    near,
    record_commands,
    robot_on_sim,
    sim_reaches,
    sim_seconds,
    time_limit,
)


async def _working(robot: galileo.Robot, target_id: int) -> None:
    await robot.wait_until(
        lambda s: s.target_num_id == target_id and s.target_status == TargetStatus.WORKING,
        timeout=WAIT,
    )


def _target_status(robot: galileo.Robot) -> TargetStatus | None:
    return None if robot.status is None else robot.status.target_status


def _no_goal(state: SimState) -> bool:
    status = state.status
    return status.target_status == TargetStatus.FREE and status.control_speed_x == 0.0


def _at(sim: Simulator, point: tuple[float, float]) -> bool:
    pose = sim.state.pose
    return near(pose.x, point[0]) and near(pose.y, point[1])


@modes()
async def test_goto_arrives(mode: Mode) -> None:
    async with robot_on_sim(mode) as (sim, robot):
        result = await robot.goto(NEAR, timeout=WAIT)
        assert (result.target_id, result.distance) == (NEAR, 0.0)
        assert result.status.target_status == TargetStatus.FREE
        assert _at(sim, TARGETS[NEAR])
        # A target behind a turn, then the same target again while standing on it.
        result = await robot.goto(RIGHT, timeout=WAIT)
        assert (result.target_id, result.distance) == (RIGHT, 0.0)
        assert _at(sim, TARGETS[RIGHT])
        result = await robot.goto(RIGHT, timeout=WAIT)
        assert result.target_id == RIGHT
        assert _at(sim, TARGETS[RIGHT])


@modes()
async def test_goto_the_goal_that_is_already_running(mode: Mode) -> None:
    async with robot_on_sim(mode) as (sim, robot):
        await robot.send(Goto(NEAR))  # e.g. from another host: the robot is on its way
        await _working(robot, NEAR)
        # The firmware restarts it; the restart's arrival is ours.
        result = await robot.goto(NEAR, timeout=WAIT)
        assert (result.target_id, result.distance) == (NEAR, 0.0)
        assert _at(sim, TARGETS[NEAR])


@modes(lambda mode: mode.real)
async def test_goto_invalid_id_on_real_firmware(mode: Mode) -> None:
    async with robot_on_sim(mode) as (sim, robot):
        # A fresh robot already shows -1 (the firmware default), so a rejection, also
        # reported as -1 with the id unchanged, shows no change at all (docs/protocol.md §2.b).
        assert robot.status is not None
        assert robot.status.target_status == TargetStatus.INVALID
        with pytest.raises(AcceptTimeout, match="real firmware reports errors as -1"):
            await robot.goto(INVALID_ID, accept_timeout=sim_seconds(10))
        assert sim.state.status.target_num_id == -1
        await robot.goto(NEAR, timeout=WAIT)
        with pytest.raises(GoalRejected) as caught:
            await robot.goto(INVALID_ID, timeout=WAIT)
        assert caught.value.target_id == INVALID_ID
        assert caught.value.status is not None
        assert caught.value.status.target_status == TargetStatus.INVALID
        assert caught.value.status.target_num_id == NEAR  # not updated by the firmware
        assert _at(sim, TARGETS[NEAR])  # the robot stayed
        await _invalid_goal_ends_the_running_one(robot, sim)


@modes(lambda mode: not mode.real)
async def test_goto_invalid_id_on_document_firmware(mode: Mode) -> None:
    async with robot_on_sim(mode) as (sim, robot):
        with pytest.raises(GoalRejected) as caught:
            await robot.goto(INVALID_ID, timeout=WAIT)
        assert caught.value.status is not None
        assert caught.value.status.target_status == TargetStatus.ERROR
        assert caught.value.status.target_num_id == INVALID_ID
        assert _at(sim, (0.0, 0.0))
        # After an error the next goal works.
        result = await robot.goto(NEAR, timeout=WAIT)
        assert result.target_id == NEAR
        await _invalid_goal_ends_the_running_one(robot, sim)


async def _invalid_goal_ends_the_running_one(robot: galileo.Robot, sim: Simulator) -> None:
    """An invalid id cancels the running goal first (docs/protocol.md §2.b), then fails."""
    running = asyncio.create_task(robot.goto(FAR, timeout=WAIT))
    try:
        await _working(robot, FAR)
        with pytest.raises(GoalRejected):
            await robot.goto(INVALID_ID, timeout=WAIT)
        with pytest.raises(GoalCancelled):
            await asyncio.wait_for(running, WAIT)
    finally:
        running.cancel()
    status = sim.state.status
    assert status.goal_failed  # the robot stands, showing the error
    assert status.control_speed_x == 0.0


@modes()
async def test_goto_point_and_dynamic_targets(mode: Mode) -> None:
    async with robot_on_sim(mode) as (sim, robot):
        with pytest.raises(NotReady, match="reset_targets"):
            await robot.add_target(1.0, 1.0)  # the robot's dynamic-target count is unknown
        await robot.reset_targets()
        target_id = await robot.add_target(-1.0, 1.0)
        assert target_id == MAP_TARGETS
        await sim_reaches(robot, sim, lambda s: len(s.targets) == MAP_TARGETS + 1)
        assert sim.state.targets[target_id] == (-1.0, 1.0)
        assert (await robot.goto(target_id, timeout=WAIT)).target_id == target_id
        assert _at(sim, (-1.0, 1.0))

        result = await robot.goto_point(0.5, 0.5, timeout=WAIT)
        # goto_point resets first: the new target takes the first dynamic id again.
        assert (result.target_id, result.distance) == (MAP_TARGETS, 0.0)
        assert sim.state.targets == (*TARGETS, (0.5, 0.5))
        assert _at(sim, (0.5, 0.5))

        await robot.reset_targets()
        await sim_reaches(robot, sim, lambda s: s.targets == TARGETS)
        with pytest.raises((GoalRejected, AcceptTimeout)):
            # Gone from the robot; real firmware shows -1 with the id unchanged.
            await robot.goto(MAP_TARGETS, timeout=WAIT, accept_timeout=sim_seconds(20))


@modes()
async def test_goto_point_nudges_a_header_inside_a_float(mode: Mode) -> None:
    # These float bytes are CD EB D7 3F: sent as is, the firmware parser would abort the
    # command at the header inside it (docs/protocol.md §2.d).
    x = struct.unpack("<f", b"\xcd\xeb\xd7\x3f")[0]
    async with robot_on_sim(mode) as (sim, robot):
        log = record_commands(sim)
        result = await robot.goto_point(x, 0.0, timeout=WAIT)
        assert result.target_id == MAP_TARGETS
        sent_x = sim.state.targets[MAP_TARGETS][0]
        assert sent_x != x
        assert math.isclose(sent_x, x, rel_tol=1e-6)
        assert near(sim.state.pose.x, sent_x)
        assert [type(command).__name__ for command, _ in log] == [
            "ResetTargets", "AddTarget", "Goto",
        ]  # fmt: skip


@modes()
async def test_pause_resume_cancel(mode: Mode) -> None:
    async with robot_on_sim(mode) as (sim, robot):
        with pytest.raises(NotReady):
            await robot.pause()  # no goal
        goal = asyncio.create_task(robot.goto(FAR, timeout=WAIT))
        try:
            await _working(robot, FAR)
            await robot.pause()
            assert _target_status(robot) == TargetStatus.PAUSED
            assert sim.state.status.control_speed_x == 0.0
            paused_at, since = sim.state.pose.x, sim.state.time
            await sim_reaches(robot, sim, lambda s: s.time > since + 2.0)
            assert sim.state.pose.x == paused_at  # paused: the robot stands
            assert not goal.done()  # paused is not an end

            await robot.resume()
            assert _target_status(robot) == TargetStatus.WORKING
            await sim_reaches(robot, sim, lambda s: s.pose.x > paused_at + 0.1)

            await robot.cancel()
            with pytest.raises(GoalCancelled) as caught:
                await asyncio.wait_for(goal, WAIT)
            assert not caught.value.preempted
        finally:
            goal.cancel()
        state = sim.state.status
        assert state.target_status == TargetStatus.FREE
        # Real firmware drops the id on cancel (docs/protocol.md §2.c); the document keeps it.
        assert state.target_num_id == (-1 if mode.real else FAR)
        assert _no_goal(sim.state)


@modes()
async def test_a_second_goto_preempts_the_first(mode: Mode) -> None:
    async with robot_on_sim(mode) as (sim, robot):
        first = asyncio.create_task(robot.goto(FAR, timeout=WAIT))
        try:
            await _working(robot, FAR)
            result = await robot.goto(NEAR, timeout=WAIT)
            assert result.target_id == NEAR
            with pytest.raises(GoalCancelled) as caught:
                await asyncio.wait_for(first, WAIT)
            assert caught.value.preempted
        finally:
            first.cancel()
        assert _at(sim, TARGETS[NEAR])

        # A goal from elsewhere (another host, the robot's HTTP API) preempts as well.
        third = asyncio.create_task(robot.goto(FAR, timeout=WAIT))
        try:
            await _working(robot, FAR)
            await robot.send(Goto(RIGHT))
            with pytest.raises(GoalCancelled) as caught:
                await asyncio.wait_for(third, WAIT)
            assert caught.value.preempted
        finally:
            third.cancel()
        await sim_reaches(robot, sim, lambda s: _at(sim, TARGETS[RIGHT]))


@modes()
async def test_leaving_a_goto_early_stops_the_robot(mode: Mode) -> None:
    async with robot_on_sim(mode) as (sim, robot):
        with pytest.raises(TimeoutError):
            async with time_limit(sim_seconds(5)):
                await robot.goto(FAR)
        # Cancel (i 2) was written before the exception left goto.
        await sim_reaches(robot, sim, _no_goal)
        assert 0.0 < sim.state.pose.x < TARGETS[FAR][0] / 2  # stopped on the way

        with pytest.raises(TimeoutError):
            with anyio.fail_after(sim_seconds(5)):
                await robot.goto(FAR)
        await sim_reaches(robot, sim, _no_goal)

        with pytest.raises(OperationTimeout):
            await robot.goto(FAR, timeout=sim_seconds(5))
        await sim_reaches(robot, sim, _no_goal)

        with pytest.raises(TimeoutError):
            async with time_limit(sim_seconds(5)):
                await robot.goto(FAR, cancel_on_exit=False)
        await sim_reaches(robot, sim, lambda s: (s.status.current_speed_x or 0.0) > 0.0)
        assert sim.state.status.target_status == TargetStatus.WORKING  # still driving
        await robot.cancel()
        await sim_reaches(robot, sim, _no_goal)


@modes()
async def test_planner_abort_is_a_goal_aborted(mode: Mode) -> None:
    async with robot_on_sim(mode, planner_abort="next") as (sim, robot):
        with pytest.raises(GoalAborted) as caught:
            await robot.goto(NEAR, timeout=WAIT)
        distance = caught.value.distance
        assert distance is not None
        assert distance > robot.arrive_tolerance
        assert near(distance, TARGETS[NEAR][0] - sim.state.pose.x, 0.01)
        assert caught.value.status is not None
        assert caught.value.status.target_status == TargetStatus.FREE
        # Only that goal was aborted: the next one arrives.
        assert (await robot.goto(NEAR, timeout=WAIT)).distance == 0.0


@modes()
async def test_busy_back_off_after_start_navigation(mode: Mode) -> None:
    # Busy outlasts the visual initialisation, so the goal meets a busy robot.
    async with robot_on_sim(mode, navigate=False, busy_on_start=6.0) as (sim, robot):
        log = record_commands(sim)
        await robot.start_navigation(timeout=WAIT)
        assert sim.state.status.busy_status == 1
        result = await robot.goto(NEAR, timeout=WAIT)
        assert result.target_id == NEAR
        goto_busy = [busy for command, busy in log if isinstance(command, Goto)]
        if mode.has("busy_status"):
            assert goto_busy == [False]  # the driver waited for busy to end
        else:
            # The layout cannot show busy: the robot queued the goal until busy ended.
            assert goto_busy == [True]

        if mode.has("busy_status"):
            sim.model.set_busy(1000.0)
            await robot.wait_until(lambda s: s.is_busy, timeout=WAIT)
            sent = robot.link.commands_sent
            with pytest.raises(OperationTimeout, match="busy"):
                await robot.goto(RIGHT, timeout=sim_seconds(10))
            assert robot.link.commands_sent == sent  # nothing was sent, not even a cancel
