"""robot.http's task chain calls against the simulator's HTTP face, on the virtual clock.

Every timeout below is virtual seconds; callback_action calls an aiohttp server on loopback.
"""

from __future__ import annotations

import asyncio
import contextlib
import sys
from collections.abc import AsyncIterator, Awaitable, Callable
from typing import Any

import anyio
import pytest
from aiohttp import web

import galileo_async as galileo
from galileo_async import HttpError, InvalidArgument
from galileo_async.http import HttpApi
from galileo_async.robot import (
    CallbackAction,
    ChargeAction,
    LocalMoveAction,
    NavAction,
    SleepAction,
    Task,
    WaitReqAction,
)
from tests.links.test_http_link import http_of
from tests.robot.goals.test_http_goals import WAIT, http_robot

pytestmark = pytest.mark.timeout(60)


async def ended(robot: galileo.Robot, task_id: str) -> Task:
    """The task once it ends, looked at once a (virtual) second."""
    with anyio.fail_after(WAIT):
        while not (task := await http_of(robot).get_task(task_id)).ended:  # noqa: ASYNC110 - polled as a client does
            await asyncio.sleep(1.0)
    return task


async def still(robot: galileo.Robot) -> None:
    await robot.wait_until(
        lambda s: not s.goal_active and s.current_speed_x == 0.0 and s.current_speed_theta == 0.0,
        timeout=WAIT,
    )


@contextlib.asynccontextmanager
async def door(
    answer: Callable[[web.Request], Awaitable[web.StreamResponse]],
) -> AsyncIterator[str]:
    """A loopback HTTP server answering every request with ``answer``; its URL."""
    app = web.Application()
    app.router.add_route("*", "/{tail:.*}", answer)
    runner = web.AppRunner(app, handle_signals=False, access_log=None)
    await runner.setup()
    site = web.TCPSite(runner, "127.0.0.1", 0)
    await site.start()
    port = runner.addresses[0][1]
    try:
        yield f"http://127.0.0.1:{port}/open"
    finally:
        await runner.cleanup()


async def test_a_chain_of_every_action_runs_to_complete() -> None:
    async with http_robot() as (_sim, robot, _face):
        http = http_of(robot)
        task = await http.create_task(
            "tour",
            [
                NavAction(x=1.0, y=0.5, theta=0.0),
                SleepAction(wait_time=2),
                LocalMoveAction(distance=-0.3, angle=0.5),
                WaitReqAction(),
                {"type": "charge_action", "x": -1.0, "y": 0.0, "theta": 0.0},
            ],
        )
        assert task.state == "WAITTING"
        assert [a.type for a in task.sub_tasks][-1] == "charge_action"
        assert task.sub_tasks[0].params == {"x": 1.0, "y": 0.5, "theta": 0.0}
        assert await http.release_wait() is False  # nothing waits yet
        started = await http.start_task(task.id)
        assert started.running
        assert task.id in http.started_tasks
        with anyio.fail_after(WAIT):
            waiting = task.sub_tasks[3].id
            while getattr((await http.get_task(task.id)).current_task, "id", None) != waiting:  # noqa: ASYNC110
                await asyncio.sleep(0.5)
        assert await http.release_wait() is True
        done = await ended(robot, task.id)
        assert done.state == "COMPLETE"
        assert done.progress == 100
        assert done.loop_count == 1
        assert task.id not in http.started_tasks
        assert robot.status is not None
        assert robot.status.charge_status in (
            galileo.ChargeStatus.CHARGING,
            galileo.ChargeStatus.CHARGED,
        )
        assert [t.id for t in await http.list_tasks()] == [task.id]


async def test_a_looping_chain_counts_passes_until_its_loop_is_cleared() -> None:
    async with http_robot() as (_, robot, _face):
        http = http_of(robot)
        task = await http.create_task("loop", [SleepAction(wait_time=1)], loop_flag=True)
        await http.start_task(task.id)
        with anyio.fail_after(WAIT):
            while (await http.get_task(task.id)).loop_count < 2:  # noqa: ASYNC110
                await asyncio.sleep(0.5)
        assert (await http.set_task_loop(task.id, False)).loop_flag is False
        done = await ended(robot, task.id)
        assert done.state == "COMPLETE"
        assert done.loop_count >= 3


async def test_pause_resume_and_stop_mid_nav_action() -> None:
    async with http_robot() as (sim, robot, _face):
        http = http_of(robot)
        task = await http.create_task("far", [NavAction(x=4.0, y=0.0)])
        await http.start_task(task.id)
        await robot.wait_until(lambda s: (s.current_pose_x or 0) > 0.5, timeout=WAIT)
        paused = await http.pause_task(task.id)
        assert paused.state == "PAUSED"
        await robot.wait_until(
            lambda s: s.target_status == galileo.TargetStatus.PAUSED, timeout=WAIT
        )
        assert (await http.resume_task(task.id)).state == "WORKING"
        await robot.wait_until(
            lambda s: s.target_status == galileo.TargetStatus.WORKING, timeout=WAIT
        )
        stopped = await http.stop_task(task.id)
        assert stopped.state == "CANCELLED"
        assert task.id not in http.started_tasks
        await still(robot)
        assert sim.model.x < 4.0


@pytest.mark.parametrize("started_by", ["this robot", "another client"])
async def test_stop_stops_a_running_chain_and_the_robot_stays_stopped(started_by: str) -> None:
    async with http_robot() as (sim, robot, face):
        http = http_of(robot)
        actions = [LocalMoveAction(distance=3.0), SleepAction(wait_time=1), NavAction(x=3, y=1)]
        if started_by == "this robot":
            task = await http.create_task("drive", actions)
            await http.start_task(task.id)
        else:
            api = HttpApi(f"http://127.0.0.1:{face.address[1]}")
            body = {"name": "drive", "sub_tasks": [a.model_dump() for a in actions]}
            task = Task.model_validate(await api.call("POST", "/task", body=body))
            await api.call("GET", "/task/start", {"id": task.id})
            await api.close()
        await robot.wait_until(lambda s: (s.current_pose_x or 0) > 0.3, timeout=WAIT)
        report = await robot.stop()
        assert report.chains == (task.id,)
        assert f"task chain {task.id} stopped" in str(report)
        assert (await http.get_task(task.id)).state == "CANCELLED"
        where = (sim.model.x, sim.model.y)
        await asyncio.sleep(10.0)
        assert (sim.model.x, sim.model.y) == where
        assert robot.status is not None
        assert not robot.status.goal_active


async def test_stop_without_a_chain_names_none() -> None:
    async with http_robot() as (_, robot, _face):
        report = await robot.stop()
        assert report.chains == ()


async def test_callback_action_ok_wrong_status_and_timeout() -> None:
    seen: list[Any] = []

    async def ok(request: web.Request) -> web.StreamResponse:
        seen.append((request.method, await request.json()))
        return web.json_response({"ok": True})

    async def refused(request: web.Request) -> web.StreamResponse:
        return web.json_response({"ok": False}, status=503)

    release = asyncio.Event()

    async def silent(request: web.Request) -> web.StreamResponse:
        await release.wait()  # past the face's timeout: no answer it waits for
        return web.json_response({"ok": True})

    async with http_robot() as (_, robot, face):
        face.callback_timeout = 5.0
        http = http_of(robot)
        for answer, state in ((ok, "COMPLETE"), (refused, "ERROR"), (silent, "ERROR")):
            async with door(answer) as url:
                action = CallbackAction(url=url, method="POST", data={"door": 1})
                task = await http.create_task("door", [action, SleepAction(wait_time=0)])
                await http.start_task(task.id)
                done = await ended(robot, task.id)
                assert done.state == state, answer.__name__
                assert done.sub_tasks[0].state == state
        release.set()
        assert seen == [("POST", {"door": 1})]
        errors = list(face.engine.errors.values())
        assert "HTTP 503" in errors[0]
        assert "no answer within 5.0 s" in errors[1]


async def test_unknown_ids_and_bad_actions_are_refused_by_the_face() -> None:
    async with http_robot() as (_, robot, face):
        http = http_of(robot)
        with pytest.raises(HttpError) as info:
            await http.get_task("nope")
        assert info.value.status == 404
        assert "no task 'nope'" in str(info.value)
        for verb in (http.start_task, http.pause_task, http.resume_task, http.stop_task):
            with pytest.raises(HttpError, match="404"):
                await verb("nope")
        api = HttpApi(f"http://127.0.0.1:{face.address[1]}")
        try:
            for action, says in (
                ({"type": "fly_action"}, "unknown action type"),
                ({"type": "upload_map_action", "server_id": "s"}, "not simulated"),
            ):
                with pytest.raises(HttpError, match=says) as info:
                    await api.call("POST", "/task", body={"name": "x", "sub_tasks": [action]})
                assert info.value.status == 400
        finally:
            await api.close()


@pytest.mark.parametrize(
    "bad",
    [
        {"type": "fly_action"},
        {"type": "nav_action", "x": 1.0},
        {"type": "nav_action", "x": float("inf"), "y": 0.0},
        {"type": "sleep_action", "wait_time": -1.0},
        {"type": "local_move_action", "method": 2},
        {"type": "callback_action", "url": "door.local"},
        {"type": "callback_action", "url": "http://door", "method": "FLY"},
        {"type": "wait_req_action", "extra": 1},
        "sleep",
    ],
)
async def test_bad_input_raises_before_anything_is_sent(bad: Any) -> None:
    async with http_robot() as (_, robot, face):
        http = http_of(robot)
        before = face.requests
        with pytest.raises(InvalidArgument, match=r"sub_tasks\[0\]"):
            await http.create_task("x", [bad])
        for call in (
            http.create_task("", []),
            http.create_task("x", {"type": "wait_req_action"}),  # type: ignore[arg-type]
            http.create_task("x", [], loop_flag=1),  # type: ignore[arg-type]
            http.get_task(""),
            http.set_task_loop("x", "yes"),  # type: ignore[arg-type]
        ):
            with pytest.raises(InvalidArgument):
                await call
        assert face.requests == before
        assert face.engine.tasks == {}


def test_action_models_dump_the_vendors_json() -> None:
    assert NavAction(x=1, y=2, theta=0.5).model_dump() == {
        "type": "nav_action", "x": 1.0, "y": 2.0, "theta": 0.5}  # fmt: skip
    assert ChargeAction(x=-1, y=0).model_dump()["type"] == "charge_action"
    assert LocalMoveAction(distance=-0.5, angle=0).model_dump() == {
        "type": "local_move_action", "distance": -0.5, "angle": 0.0, "method": 0}  # fmt: skip
    lift = "http://lift/call"
    assert CallbackAction(url=lift).model_dump() == {
        "type": "callback_action", "url": lift, "method": "POST", "data": {}}  # fmt: skip
    assert WaitReqAction().model_dump() == {"type": "wait_req_action"}


CallRoute = Callable[[Callable[[], Awaitable[object]]], Awaitable[None]]


async def _fail_after(call: Callable[[], Awaitable[object]]) -> None:
    with pytest.raises(TimeoutError):
        with anyio.fail_after(0):
            await call()


async def _move_on_after(call: Callable[[], Awaitable[object]]) -> None:
    with anyio.move_on_after(0) as scope:
        await call()
    assert scope.cancelled_caught


async def _asyncio_timeout(call: Callable[[], Awaitable[object]]) -> None:
    if sys.version_info < (3, 11):
        pytest.skip("asyncio.timeout needs Python 3.11")
    with pytest.raises(TimeoutError):
        async with asyncio.timeout(0):
            await call()


async def _task_cancel(call: Callable[[], Awaitable[object]]) -> None:
    task = asyncio.ensure_future(call())
    await asyncio.sleep(0)
    task.cancel()
    with pytest.raises(asyncio.CancelledError):
        await task


async def _failing_sibling(call: Callable[[], Awaitable[object]]) -> None:
    async def fail() -> None:
        raise RuntimeError("sibling")

    async def group() -> None:
        async with anyio.create_task_group() as tasks:
            tasks.start_soon(call)
            tasks.start_soon(fail)

    with pytest.raises(Exception) as caught:  # noqa: PT011 - a group holding it: checked below
        await group()
    assert "sibling" in repr(caught.value)


@pytest.mark.parametrize(
    "route", [_fail_after, _move_on_after, _asyncio_timeout, _task_cancel, _failing_sibling]
)
async def test_a_cancelled_task_call_leaves_nothing_running(route: CallRoute) -> None:
    async with http_robot() as (_, robot, face):
        http = http_of(robot)
        task = await http.create_task("t", [SleepAction(wait_time=1)])
        calls: list[Callable[[], Awaitable[object]]] = [
            lambda: http.create_task("u", [SleepAction(wait_time=1)]),
            lambda: http.get_task(task.id),
            http.list_tasks,
            lambda: http.start_task(task.id),
            lambda: http.pause_task(task.id),
            lambda: http.resume_task(task.id),
            lambda: http.stop_task(task.id),
            lambda: http.set_task_loop(task.id, True),
            http.release_wait,
        ]
        for call in calls:
            await route(call)
        # The link still carries calls, and the chain still runs to its end when started.
        await http.start_task(task.id)
        assert (await ended(robot, task.id)).state == "COMPLETE"
        await http.delete_task(task.id)
        assert task.id not in face.engine.tasks
