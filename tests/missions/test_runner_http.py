"""Steps of the http:// link (say, switch_map, goto_pose) and call steps, on the simulator."""

from __future__ import annotations

import contextlib
import math
from collections.abc import AsyncIterator
from typing import Any

import pytest
from aiohttp import web

from galileo_async.missions import Mission, run_mission
from galileo_async.testing import simulated_robot

pytestmark = pytest.mark.timeout(60)


def mission(*steps: Any, **fields: Any) -> Mission:
    return Mission.model_validate({"mission": "test", **fields, "steps": list(steps)})


async def test_say_switch_map_and_goto_pose_over_http() -> None:
    plan = mission(
        {"say": "hello"},
        {"switch_map": {"map": "floor2", "path": "path2"}},
        {"goto_pose": {"x": 1.0, "y": 1.0, "theta": 1.0}},
        {"goto": 1},
    )
    async with simulated_robot(link="http") as (robot, device):
        report = await run_mission(robot, plan)
        face = device.http_face
        assert face is not None
        assert face.spoken == ["hello"]
        assert face.current == ("floor2", "path2")
    assert [s.ending for s in report.steps] == ["done", "done", "reached", "reached"]
    assert report.steps[2].distance_m == pytest.approx(math.sqrt(2), abs=0.3)


async def test_a_map_that_does_not_exist_fails_the_step() -> None:
    plan = mission({"switch_map": "basement", "on_failure": "skip"}, {"say": "still here"})
    async with simulated_robot(link="http") as (robot, device):
        report = await run_mission(robot, plan)
        assert device.http_face is not None
        assert device.http_face.spoken == ["still here"]
    assert [s.ending for s in report.steps] == ["skipped", "done"]
    assert report.steps[0].error


@contextlib.asynccontextmanager
async def door(answer: Any, status: int = 200) -> AsyncIterator[tuple[str, list[Any]]]:
    """An outside system on loopback: every request's JSON body is kept; it answers ``answer``."""
    got: list[Any] = []

    async def handle(request: web.Request) -> web.Response:
        got.append(await request.json() if request.can_read_body else None)
        return web.json_response(answer, status=status)

    app = web.Application()
    app.router.add_route("*", "/open", handle)
    runner = web.AppRunner(app)
    await runner.setup()
    site = web.TCPSite(runner, "127.0.0.1", 0)
    await site.start()
    port = runner.addresses[0][1]
    try:
        yield f"http://127.0.0.1:{port}/open", got
    finally:
        await runner.cleanup()


async def test_a_call_step_sends_its_body_and_checks_the_answer() -> None:
    async with door({"ok": True, "door": {"id": 1, "state": "open"}}) as (url, got):
        plan = mission(
            {"call": {"url": url, "json": {"door": 1}, "expect_json": {"door": {"state": "open"}}}}
        )
        async with simulated_robot() as (robot, _):
            report = await run_mission(robot, plan)
    assert got == [{"door": 1}]
    assert [s.ending for s in report.steps] == ["done"]


@pytest.mark.parametrize(
    ("answer", "status", "call", "error"),
    [
        ({"ok": True}, 500, {}, "status 500, expected 200"),
        ({"ok": False}, 200, {"expect_json": {"ok": True}}, "does not hold"),
        ({"ok": True}, 201, {"expect_status": [200, 204]}, "expected 200 or 204"),
    ],
)
async def test_a_call_step_with_the_wrong_answer_fails(
    answer: Any, status: int, call: dict[str, Any], error: str
) -> None:
    async with door(answer, status) as (url, _):
        plan = mission({"call": {"url": url, **call}})
        async with simulated_robot() as (robot, _):
            report = await run_mission(robot, plan)
    assert report.ending == "failed"
    assert report.steps[0].ending == "failed"
    assert error in (report.steps[0].error or "")


async def test_a_call_to_nobody_fails() -> None:
    async with door({}) as (url, _):
        pass  # the port is free again: nothing listens
    plan = mission({"call": {"url": url, "timeout": 2}, "on_failure": "skip"})
    async with simulated_robot() as (robot, _):
        report = await run_mission(robot, plan)
    assert report.steps[0].ending == "skipped"
