"""Offloading a mission to the robot's task chain: against the simulator's HTTP face.

On the virtual clock: every time below is virtual seconds; call steps call an aiohttp
server on loopback (tests/robot/test_http_tasks.py's door).
"""

from __future__ import annotations

import asyncio
import logging
import math
from typing import Any

import anyio
import pytest
from aiohttp import web

import galileo_async as galileo
from galileo_async import InvalidArgument, NotSupported
from galileo_async.missions import Mission
from galileo_async.missions.offload import (
    ActionRun,
    ChainProgress,
    OffloadRejected,
    OffloadReport,
    offload_mission,
    offload_problems,
    plan_offload,
)
from galileo_async.robot import (
    CallbackAction,
    ChargeAction,
    LocalMoveAction,
    NavAction,
    NavPoint,
    SleepAction,
    WaitReqAction,
)
from galileo_async.sim.http import HttpFace
from galileo_async.testing import simulated_robot
from tests.links.test_http_link import http_of
from tests.robot.goals.test_http_goals import TARGETS, WAIT, http_robot
from tests.robot.test_http_tasks import door, still
from tests.support.cancel_ways import WAYS, stop_waiting

pytestmark = pytest.mark.timeout(60)

ROBOT_TARGETS = [NavPoint(1.5, 0.0, 0.0), NavPoint(3.0, 0.0, 1.0)]
DOCK = NavPoint(-1.0, 0.0, math.pi)


def mission(*steps: Any, **fields: Any) -> Mission:
    return Mission.model_validate({"mission": "m", "steps": list(steps), **fields})


def forever(*steps: Any) -> Mission:
    return mission({"loop": {"count": "forever", "steps": list(steps)}})


# --- the translation ----------------------------------------------------------------


def test_every_offloadable_step_becomes_its_action() -> None:
    plan = plan_offload(
        mission(
            {"goto": 1, "name": "lab"},
            {"goto_point": {"x": 1.0, "y": 2.0}},
            {"goto_pose": {"x": 1.0, "y": 2.0, "theta": 1.5}},
            {"dwell": 2.5},
            {"charge": None},
            {"local_move": {"distance": -0.5, "angle": 0.25}},
            {"call": {"url": "http://door.local/open", "method": "PUT", "json": {"door": 1}}},
            {"call": {"url": "http://lift.local/call"}},
            {"wait": "operator"},
        ),
        targets=ROBOT_TARGETS,
        charge_pose=DOCK,
    )
    assert plan.actions == [
        NavAction(x=3.0, y=0.0, theta=1.0),  # the target's saved heading
        NavAction(x=1.0, y=2.0, theta=0.0),  # a point has none: 0, as goto_point's goal
        NavAction(x=1.0, y=2.0, theta=1.5),
        SleepAction(wait_time=2.5),
        ChargeAction(x=-1.0, y=0.0, theta=math.pi),
        LocalMoveAction(distance=-0.5, angle=0.25),
        CallbackAction(url="http://door.local/open", method="PUT", data={"door": 1}),
        CallbackAction(url="http://lift.local/call", method="POST", data={}),
        WaitReqAction(),
    ]
    assert [s.path for s in plan.steps][:2] == ["steps[0]", "steps[1]"]
    assert (plan.steps[0].name, plan.steps[0].action) == ("lab", "goto")
    assert (plan.name, plan.loop_flag, plan.count) == ("m", False, None)


@pytest.mark.parametrize(
    ("count", "loop_flag", "kept"), [(3, True, 3), ("forever", True, None), (1, False, None)]
)
def test_a_whole_mission_loop_is_the_loop_flag(count: Any, loop_flag: bool, kept: Any) -> None:
    plan = plan_offload(mission({"loop": {"count": count, "steps": [{"dwell": 1}, {"goto": 0}]}}),
                        targets=ROBOT_TARGETS)  # fmt: skip
    assert (plan.loop_flag, plan.count) == (loop_flag, kept)
    assert [s.path for s in plan.steps] == ["steps[0].loop.steps[0]", "steps[0].loop.steps[1]"]
    assert plan.actions == [SleepAction(wait_time=1), NavAction(x=1.5, y=0.0, theta=0.0)]


@pytest.mark.parametrize(
    ("steps", "says"),
    [
        ([{"say": "hi"}], "steps[0]: say: the task chain has no speech action"),
        ([{"switch_map": "floor2", "name": "up"}], "steps[0] (up): switch_map: the task chain"),
        ([{"dwell": 1}, {"loop": {"steps": [{"dwell": 1}]}}], "steps[1]: a loop among other"),
        (
            [{"loop": {"steps": [{"dwell": 1}, {"loop": {"count": 2, "steps": [{"dwell": 1}]}}]}}],
            "steps[0].loop.steps[1]: a loop inside the loop",
        ),
        ([{"goto": 1, "on_failure": "retry 2"}], "steps[0]: on_failure retry 2: the task chain"),
        ([{"goto": 1, "on_failure": "skip"}], "on_failure skip: the task chain ends at the first"),
        (
            [{"goto": 1, "name": "a", "on_failure": "goto dock"}, {"charge": None, "name": "dock"}],
            "steps[0] (a): on_failure goto dock",
        ),
        ([{"loop": {"steps": [{"dwell": 1}]}, "timeout": 60}], "steps[0]: timeout 60 s"),
        ([{"dwell": 5, "timeout": 3}], "steps[0]: timeout 3 s: the task chain has no step"),
        ([{"charge": {"until_percent": 90}}], "charge until a battery level"),
        ([{"charge": {"until_volts": 25.2}}], "charge until a battery level"),
        ([{"call": {"url": "http://d/", "headers": {"X": "1"}}}], "call headers"),
        ([{"call": {"url": "http://d/", "expect_status": 200}}], "call expect_status"),
        ([{"call": {"url": "http://d/", "expect_json": {"ok": True}}}], "call expect_json"),
        ([{"call": {"url": "http://d/", "timeout": 3}}], "call timeout"),
        ([{"call": {"url": "http://d/", "json": [1, 2]}}], "call json: the robot's callback"),
        ([{"wait": {"release": "op", "timeout": 60}}], "steps[0]: wait timeout"),
    ],
)
def test_each_problem_is_named(steps: list[Any], says: str) -> None:
    problems = offload_problems(mission(*steps))
    assert len(problems) == 1, problems
    assert says in problems[0]
    with pytest.raises(OffloadRejected, match="cannot be offloaded") as info:
        plan_offload(mission(*steps), targets=ROBOT_TARGETS, charge_pose=DOCK)
    assert info.value.problems == problems


def test_problems_that_need_the_robots_answers() -> None:
    plan = mission({"goto": 2, "name": "far"}, {"charge": None}, {"goto": 1})
    assert offload_problems(plan) == []  # targets not given: not checked
    assert offload_problems(plan, targets=ROBOT_TARGETS) == [
        "steps[0] (far): goto 2: the robot's current map and path have no target 2 (2 targets)"
    ]
    with pytest.raises(OffloadRejected) as info:
        plan_offload(plan, targets=ROBOT_TARGETS)
    assert info.value.problems[1] == "steps[1]: charge: the charger's pose is not known"


def test_every_problem_is_named_at_once() -> None:
    problems = offload_problems(
        mission({"say": "a"}, {"dwell": 1, "on_failure": "skip", "timeout": 2}, {"switch_map": "b"})
    )
    assert [p.split(":")[0] for p in problems] == ["steps[0]", "steps[1]", "steps[1]", "steps[2]"]


# --- on the simulator's HTTP face ---------------------------------------------------


def _task(face: HttpFace, report: OffloadReport) -> dict[str, Any]:
    return face.engine.get(report.task_id)


async def test_a_mission_of_every_robot_side_step_runs_to_complete() -> None:
    seen: list[ChainProgress] = []
    plan = mission(
        {"goto": 1, "name": "far"},
        {"dwell": 3},
        {"goto_point": {"x": 1.0, "y": 0.5}},
        {"local_move": {"distance": -0.3, "angle": 0.5}},
        {"goto_pose": {"x": 0.0, "y": 0.0, "theta": 0.0}},
        {"charge": None},
    )
    async with http_robot() as (sim, robot, face):
        assert await http_of(robot).charge_pose() == NavPoint(*sim.model.dock, 0.0)
        with anyio.fail_after(WAIT):
            report = await offload_mission(robot, plan, on_progress=seen.append)
        assert report.ending == "completed", report.error
        assert report.completed
        task = _task(face, report)
        assert task["state"] == "COMPLETE"
        assert [a["type"] for a in task["sub_tasks"]] == [
            "nav_action", "sleep_action", "nav_action", "local_move_action", "nav_action",
            "charge_action",
        ]  # fmt: skip
        assert task["sub_tasks"][0]["x"] == TARGETS[1][0]
        assert task["sub_tasks"][-1]["x"] == sim.model.dock[0]
        assert [(r.index, r.state) for r in report.actions] == [(i, "COMPLETE") for i in range(6)]
        assert report.actions[0].name == "far"
        assert all(r.loop == 1 and r.ended is not None for r in report.actions)
        # dwell 3 s, looked at once a second: its run spans at least 2 s of looks
        dwell = report.actions[1]
        assert dwell.ended is not None
        assert dwell.ended - dwell.started >= 2.0
        assert robot.status is not None
        assert robot.status.charge_status in (
            galileo.ChargeStatus.CHARGING,
            galileo.ChargeStatus.CHARGED,
        )
        started = [p.run.index for p in seen if p.run.ended is None]
        ended = [p.run.index for p in seen if p.run.ended is not None]
        assert started == list(range(6))
        assert ended == list(range(6))
        assert all(p.task_id == report.task_id and p.mission == "m" for p in seen)


async def test_the_follower_looks_once_a_period() -> None:
    async with http_robot() as (_, robot, face):
        before = face.requests
        report = await offload_mission(robot, mission({"dwell": 10}), period=2.0)
        assert report.completed
        looks = face.requests - before - 2  # create and start
        assert 4 <= looks <= 7, looks  # 10 s at one look every 2 s
        with pytest.raises(InvalidArgument, match="period must be at least 1"):
            await offload_mission(robot, mission({"dwell": 1}), period=0.5)
        for bad in ({"follow_timeout": 0}, {"call_timeout": math.inf}):
            with pytest.raises(InvalidArgument):
                await offload_mission(robot, mission({"dwell": 1}), **bad)


async def test_a_counted_loop_runs_its_passes_and_ends_complete() -> None:
    plan = mission({"loop": {"count": 3, "steps": [{"goto": 0}, {"dwell": 2}, {"goto": 1}]}})
    async with http_robot() as (_, robot, face):
        with anyio.fail_after(WAIT * 3):
            report = await offload_mission(robot, plan)
        assert report.ending == "completed", report.error
        task = _task(face, report)
        # the loop flag was cleared in the last pass: the chain ended by itself
        assert (task["state"], task["loop_count"], task["loop_flag"]) == ("COMPLETE", 3, False)
        assert report.loops_done == 3
        assert [(r.loop, r.index) for r in report.actions] == [
            (p, i) for p in (1, 2, 3) for i in range(3)
        ]
        assert all(r.state == "COMPLETE" for r in report.actions)


async def test_a_counted_loop_seen_past_its_count_is_stopped() -> None:
    # Passes of sleep 0 end within one look: the follower sees the count passed, and stops it.
    plan = mission({"loop": {"count": 2, "steps": [{"dwell": 0}]}})
    async with http_robot() as (_, robot, face):
        report = await offload_mission(robot, plan)
        assert report.ending == "completed", report.error
        assert report.loops_done == 2
        assert _task(face, report)["state"] == "CANCELLED"
        assert _task(face, report)["loop_count"] > 2
        assert face.engine.running is None
        assert all(r.loop <= 2 for r in report.actions)


async def test_a_forever_loop_runs_until_robot_stop() -> None:
    plan = forever({"goto": 0}, {"dwell": 1}, {"goto": 1}, {"dwell": 1})
    async with http_robot() as (sim, robot, face):
        passes = asyncio.Event()

        def progress(event: ChainProgress) -> None:
            if event.loops_done >= 2:
                passes.set()

        runner = asyncio.ensure_future(offload_mission(robot, plan, on_progress=progress))
        with anyio.fail_after(WAIT * 2):
            await passes.wait()
        stopped = await robot.stop()
        with anyio.fail_after(WAIT):
            report = await runner
        assert stopped.chains == (report.task_id,)
        assert report.ending == "stopped"
        assert "stopped" in (report.error or "")
        assert report.loops_done >= 2
        assert _task(face, report)["state"] == "CANCELLED"
        await still(robot)
        where = (sim.model.x, sim.model.y)
        await asyncio.sleep(10.0)
        assert (sim.model.x, sim.model.y) == where


async def test_a_wait_is_released_through_robot_http() -> None:
    plan = mission({"dwell": 1}, {"wait": "operator", "name": "hold"}, {"dwell": 1})
    async with http_robot() as (_, robot, face):
        waiting = asyncio.Event()
        runs: list[ActionRun] = []

        def progress(event: ChainProgress) -> None:
            runs.append(event.run)
            if event.run.type == "wait_req_action" and event.run.ended is None:
                waiting.set()

        runner = asyncio.ensure_future(offload_mission(robot, plan, on_progress=progress))
        with anyio.fail_after(WAIT):
            await waiting.wait()
        await asyncio.sleep(30.0)
        assert not runner.done()  # it waits as long as nobody releases it
        assert await http_of(robot).release_wait() is True
        with anyio.fail_after(WAIT):
            report = await runner
        assert report.completed
        hold = report.actions[1]
        assert (hold.name, hold.action, hold.state) == ("hold", "wait", "COMPLETE")
        assert hold.ended is not None
        assert hold.ended - hold.started >= 30.0
        assert _task(face, report)["state"] == "COMPLETE"


async def test_a_call_step_is_made_by_the_robot() -> None:
    bodies: list[Any] = []

    async def ok(request: web.Request) -> web.StreamResponse:
        bodies.append((request.method, await request.json()))
        return web.json_response({"ok": True})

    async def refused(request: web.Request) -> web.StreamResponse:
        return web.json_response({}, status=409)

    async with http_robot() as (_, robot, _face):
        async with door(ok) as url:
            call = {"url": url, "method": "PUT", "json": {"door": 1}}
            report = await offload_mission(robot, mission({"call": call}, {"dwell": 1}))
        assert report.completed
        assert bodies == [("PUT", {"door": 1})]
        async with door(refused) as url:
            failing = mission({"dwell": 1}, {"call": {"url": url}, "name": "door"}, {"dwell": 1})
            report = await offload_mission(robot, failing)
        assert report.ending == "failed"
        assert report.error == "steps[1] (door): callback_action ended ERROR"
        assert [r.state for r in report.actions] == ["COMPLETE", "ERROR"]


def _drop_host(face: HttpFace, down: bool) -> None:
    """The host's network goes (every request refused, the status socket cut) or comes back."""
    face.closed = down
    if down:
        for request, _ in list(face.sockets.values()):
            if request.transport is not None:
                request.transport.abort()


async def test_the_chain_goes_on_while_the_host_is_away(caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.INFO, logger="galileo_async.missions.offload")
    plan = mission({"goto": 1}, {"dwell": 20}, {"goto": 0})
    async with http_robot() as (sim, robot, face):
        started = asyncio.Event()

        def progress(event: ChainProgress) -> None:
            if event.run.index == 1:
                started.set()

        runner = asyncio.ensure_future(offload_mission(robot, plan, on_progress=progress))
        with anyio.fail_after(WAIT):
            await started.wait()
        _drop_host(face, True)
        task_id = next(iter(face.engine.tasks))
        with anyio.fail_after(WAIT):
            while face.engine.get(task_id)["state"] != "COMPLETE":  # noqa: ASYNC110 - the robot's own view
                await asyncio.sleep(1.0)
        assert not runner.done()  # still trying, with back-off
        await asyncio.sleep(20.0)
        tries = [r.message for r in caplog.records if "no answer" in r.message]
        assert len(tries) >= 3, tries
        _drop_host(face, False)
        with anyio.fail_after(WAIT):
            report = await runner
        assert report.ending == "completed", report.error
        assert report.state == "COMPLETE"
        assert [r.state for r in report.actions] == ["COMPLETE"] * 3
        assert math.hypot(sim.model.x - TARGETS[0][0], sim.model.y - TARGETS[0][1]) < 0.3
        assert robot.link.reconnects >= 1


async def test_a_host_away_past_follow_timeout_reports_link_lost_and_the_chain_goes_on() -> None:
    plan = mission({"dwell": 1}, {"dwell": 600})
    async with http_robot() as (_, robot, face):
        started = asyncio.Event()
        runner = asyncio.ensure_future(
            offload_mission(robot, plan, follow_timeout=60.0, on_progress=lambda e: started.set())
        )
        with anyio.fail_after(WAIT):
            await started.wait()
        _drop_host(face, True)
        with anyio.fail_after(WAIT * 2):
            report = await runner
        assert report.ending == "link lost"
        assert "the chain goes on" in (report.error or "")
        assert face.engine.get(report.task_id)["state"] == "WORKING"  # the robot carries on
        _drop_host(face, False)
        with anyio.fail_after(WAIT):
            while True:
                try:
                    stopped = await robot.stop()
                    break
                except galileo.GalileoConnectionError:
                    await asyncio.sleep(1.0)
        assert stopped.chains == (report.task_id,)


@pytest.mark.parametrize("how", WAYS)
async def test_each_cancellation_way_stops_the_chain_and_the_robot(how: str) -> None:
    plan = forever({"goto": 1}, {"goto": 0})
    async with http_robot() as (sim, robot, face):
        await stop_waiting(how, lambda: offload_mission(robot, plan), after=3.0)
        (task,) = face.engine.tasks.values()
        assert task["state"] == "CANCELLED"
        assert face.engine.running is None
        await still(robot)
        where = (sim.model.x, sim.model.y)
        await asyncio.sleep(10.0)
        assert (sim.model.x, sim.model.y) == where


async def test_nothing_is_sent_for_a_mission_the_chain_cannot_run() -> None:
    async with http_robot() as (_, robot, face):
        with pytest.raises(OffloadRejected, match="no target 7"):
            await offload_mission(robot, mission({"goto": 7}))
        with pytest.raises(OffloadRejected, match="say"):
            await offload_mission(robot, mission({"say": "hi"}))
        assert face.engine.tasks == {}
    async with simulated_robot() as (robot, _device):
        with pytest.raises(NotSupported, match="http:// or https://"):
            await offload_mission(robot, mission({"dwell": 1}))


async def test_a_task_the_robot_no_longer_holds_ends_failed() -> None:
    async with http_robot() as (_, robot, face):
        started = asyncio.Event()
        runner = asyncio.ensure_future(
            offload_mission(robot, mission({"dwell": 60}), on_progress=lambda e: started.set())
        )
        with anyio.fail_after(WAIT):
            await started.wait()
        (task_id,) = face.engine.tasks
        face.engine.delete(task_id)  # as after the robot's restart: GET /task answers 404
        with anyio.fail_after(WAIT):
            report = await runner
        assert report.ending == "failed"
        assert report.error == f"the robot no longer holds task {task_id}"
        assert [(r.index, r.ended) for r in report.actions] == [(0, None)]


async def test_a_failing_progress_callback_is_logged_and_the_chain_followed_on(
    caplog: pytest.LogCaptureFixture,
) -> None:
    def broken(_progress: object) -> None:
        raise RuntimeError("callback bug")

    async with http_robot() as (_, robot, _face):
        with anyio.fail_after(WAIT):
            report = await offload_mission(robot, mission({"dwell": 3}), on_progress=broken)
    assert report.ending == "completed", report.error
    assert "on_progress failed" in caplog.text
