"""http:// against the simulator's HTTP face (REST + WebSocket) and bare servers, on loopback."""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import subprocess
import sys
from collections.abc import AsyncIterator
from dataclasses import astuple
from typing import Any

import pytest
from aiohttp import web

import galileo_async as galileo
from galileo_async import (
    GoalCancelled,
    HttpError,
    InvalidArgument,
    NotSupported,
    TargetStatus,
)
from galileo_async.events import ConnectionLostEvent, ConnectionRestored, LinkStaleEvent
from galileo_async.http import HttpApi, parse_http_url, redact_http_url
from galileo_async.links import link_kind
from galileo_async.protocol import ApiCall, RawCommand, RotateTo, Stop, Velocity
from galileo_async.robot import HttpPart
from galileo_async.sim import Simulator
from tests.support.cancel_ways import WAYS, stop_waiting

pytestmark = pytest.mark.timeout(60)

WAIT = 10.0
SPEED = 40.0
TARGETS = ((1.5, 0.0), (30.0, 0.0))


@contextlib.asynccontextmanager
async def robot_on_http(
    robot_options: dict[str, Any] | None = None, token_check: bool = False, **sim_options: Any
) -> AsyncIterator[tuple[Simulator, galileo.Robot, Any]]:
    """A simulator serving HTTP on 127.0.0.1 and a Robot on http:// to it (and the face)."""
    options: dict[str, Any] = {"speed": SPEED, "targets": TARGETS, **sim_options}
    async with Simulator(**options) as sim:
        face = await sim.serve_http(token_check=token_check)
        url = f"http://127.0.0.1:{face.address[1]}?ws_port={face.ws_address[1]}"
        async with galileo.connect(url, map_targets=len(TARGETS), **(robot_options or {})) as robot:
            yield sim, robot, face


def http_of(robot: galileo.Robot) -> HttpPart:
    """``robot.http``, which an http:// Robot has."""
    assert robot.http is not None
    return robot.http


async def navigating(robot: galileo.Robot) -> None:
    await robot.wait_until(lambda s: True, timeout=WAIT)
    await robot.start_navigation(timeout=WAIT)


# --- the URL and its options -------------------------------------------------------------


def test_url_forms_and_secrets_never_shown() -> None:
    assert link_kind("http://10.0.0.5") == link_kind("https://10.0.0.5") == "http"
    address = parse_http_url("http://admin:s3cret@10.0.0.5?ws_port=4000")
    assert address.base_url == "http://10.0.0.5:3546"
    assert address.ws_port == 4000
    assert address.password is not None
    assert address.password.get_secret_value() == "s3cret"
    assert "s3cret" not in repr(address)
    assert redact_http_url("http://admin:s3cret@h:1?token=abc&ws_port=2") == (
        "http://admin:***@h:1?token=***&ws_port=2"
    )
    for bad in ("http://", "http://host:port", "http://h?x=1"):
        with pytest.raises(InvalidArgument):
            parse_http_url(bad)


async def test_options_checked_before_anything_opens() -> None:
    with pytest.raises(InvalidArgument, match="ws_port"):
        galileo.connect("http://127.0.0.1:1", ws_port=0)
    with pytest.raises(InvalidArgument, match="layout"):
        galileo.connect("http://127.0.0.1:1", layout="v1")
    with pytest.raises(InvalidArgument) as info:
        galileo.connect("http://u:hunter2@127.0.0.1:1", nonsense=1)
    assert "hunter2" not in str(info.value)


async def test_a_failed_connect_names_no_password() -> None:
    async with Simulator(speed=SPEED) as sim:
        face = await sim.serve_http(token_check=True)
        url = f"http://admin:Pa55word9@127.0.0.1:{face.address[1]}?ws_port={face.ws_address[1]}"
        with pytest.raises(HttpError) as info:
            await galileo.connect(url, reconnect=False)
        assert "Pa55word9" not in str(info.value)
        assert "Pa55word9" not in repr(info.value)
        assert info.value.endpoint == "/token"


# --- every operation ----------------------------------------------------------------------


async def test_status_arrives_as_from_a_serial_link() -> None:
    async with robot_on_http() as (sim, robot, face):
        status = await robot.wait_until(lambda s: s.power is not None, timeout=WAIT)
        assert status.power == pytest.approx(sim.state.status.power)
        assert robot.link.frames > 0
        assert face.sockets


async def test_goto_by_index_pause_resume_and_cancel() -> None:
    async with robot_on_http() as (sim, robot, face):
        await navigating(robot)
        result = await robot.goto(0, timeout=WAIT)
        assert result.target_id == 0
        assert sim.state.pose.x == pytest.approx(1.5, abs=0.3)
        far = asyncio.ensure_future(robot.goto(1, timeout=WAIT))
        await robot.wait_until(lambda s: s.target_status == TargetStatus.WORKING, timeout=WAIT)
        await robot.pause(timeout=WAIT)
        assert sim.state.status.target_status == TargetStatus.PAUSED
        await robot.resume(timeout=WAIT)
        await robot.cancel(timeout=WAIT)
        with pytest.raises(galileo.GoalCancelled):
            await far
        calls = [task["state"] for task in face.tasks.values()]
        assert calls == ["COMPLETE", "CANCELLED"]
        await robot.stop_navigation(timeout=WAIT)
        assert not sim.state.status.navigating


async def test_goto_pose_returns_the_tasks_result() -> None:
    async with robot_on_http() as (sim, robot, _):
        await navigating(robot)
        result = await http_of(robot).goto_pose(1.0, 1.0, 0.5, timeout=WAIT)
        assert result.target_id == -2
        assert result.distance is not None
        assert result.distance < 0.3
        assert sim.state.pose.y == pytest.approx(1.0, abs=0.3)


async def test_goto_point_is_one_nav_task_followed_by_the_goal_rule() -> None:
    async with robot_on_http() as (sim, robot, face):
        await navigating(robot)
        result = await robot.goto_point(0.5, -1.0, timeout=WAIT)
        assert result.target_id == -2
        assert sim.state.pose.y == pytest.approx(-1.0, abs=0.3)
        assert len(sim.state.targets) == len(TARGETS)  # no target added
        again = await robot.goto_point(1.0, -1.0, timeout=WAIT)  # -2 again: a new goal
        assert not again.already_there
        assert sim.state.pose.x == pytest.approx(1.0, abs=0.3)
        assert [task["state"] for task in face.tasks.values()] == ["COMPLETE", "COMPLETE"]


@pytest.mark.parametrize("how", WAYS)
async def test_goto_and_goto_point_cancelled_stop_the_robot(how: str) -> None:
    async with robot_on_http() as (sim, robot, face):
        await navigating(robot)
        await stop_waiting(how, lambda: robot.goto(1, timeout=WAIT), 0.3)
        await robot.wait_until(lambda s: not s.goal_active, timeout=WAIT)
        await stop_waiting(how, lambda: robot.goto_point(40.0, 5.0, timeout=WAIT), 0.3)
        await robot.wait_until(lambda s: not s.goal_active, timeout=WAIT)
        assert [task["state"] for task in face.tasks.values()] == ["CANCELLED", "CANCELLED"]
        assert not sim.state.status.goal_active


async def test_goto_pose_cancelled_by_the_user_is_goal_cancelled() -> None:
    async with robot_on_http() as (_, robot, face):
        await navigating(robot)
        going = asyncio.ensure_future(http_of(robot).goto_pose(40.0, 0.0, timeout=WAIT))
        await robot.wait_until(lambda s: s.target_num_id == -2 and s.goal_active, timeout=WAIT)
        await robot.cancel(timeout=WAIT)
        with pytest.raises(GoalCancelled) as info:
            await going
        assert (info.value.target_id, info.value.preempted) == (-2, False)
        assert [task["state"] for task in face.tasks.values()] == ["CANCELLED"]


async def test_goto_pose_with_navigation_closed_is_not_ready_nothing_sent() -> None:
    async with robot_on_http() as (_, robot, face):
        await robot.wait_until(lambda s: True, timeout=WAIT)
        with pytest.raises(galileo.NotReady, match="navigation must be open"):
            await http_of(robot).goto_pose(1.0, 0.0, timeout=WAIT)
        assert face.tasks == {}


@pytest.mark.parametrize("how", WAYS)
async def test_goto_pose_cancelled_stops_the_task(how: str) -> None:
    async with robot_on_http() as (sim, robot, face):
        await navigating(robot)
        await stop_waiting(how, lambda: http_of(robot).goto_pose(40.0, 0.0, timeout=WAIT), 0.3)
        await robot.wait_until(lambda s: not s.goal_active, timeout=WAIT)  # as goto's cancel
        assert [task["state"] for task in face.tasks.values()] == ["CANCELLED"]
        assert not sim.state.status.goal_active


async def test_drive_puts_the_speed_and_stops_on_exit() -> None:
    async with robot_on_http() as (sim, robot, _):
        await navigating(robot)
        async with robot.drive(0.3, 0.2):
            await robot.wait_until(lambda s: (s.control_speed_x or 0) > 0.25, timeout=WAIT)
            assert sim.model.control_w == pytest.approx(0.2)
        await robot.wait_until(lambda s: s.control_speed_x == 0, timeout=WAIT)


async def test_charging_and_shutdown() -> None:
    async with robot_on_http() as (sim, robot, _):
        await navigating(robot)
        await robot.start_charging(timeout=WAIT)
        await robot.stop_charging(timeout=WAIT)
        async with asyncio.timeout(WAIT):
            events = robot.events()
            await robot.shutdown_host(confirm=True)
            async for event in events:  # the robot goes silent: its link is lost
                if isinstance(event, ConnectionLostEvent):
                    break
        assert sim.state.shutdown


async def test_http_only_methods() -> None:
    async with robot_on_http() as (_, robot, face):
        assert await http_of(robot).maps() == ["sim", "floor2"]
        assert (await http_of(robot).current_map()).map == "sim"
        switched = await http_of(robot).switch_map("floor2", "path2")
        assert (switched.map, switched.path) == ("floor2", "path2")
        assert (await http_of(robot).current_map()).path == "path2"
        points = await http_of(robot).targets()
        assert [(p.x, p.y) for p in points] == list(TARGETS)
        info = await http_of(robot).info()
        assert info.version == "5.1.0"
        assert info.code_name
        assert 0 <= (await http_of(robot).battery_percent() or 0) <= 100
        await http_of(robot).say("hello")
        assert face.spoken == ["hello"]


async def test_commands_without_an_http_form_are_not_supported_nothing_sent() -> None:
    async with robot_on_http() as (_, robot, _face):
        await navigating(robot)
        sent = robot.link.commands_sent
        with pytest.raises(NotSupported, match="no HTTP API form"):
            await robot.rotate_to(90)
        with pytest.raises(NotSupported):
            await robot.forward(20)
        with pytest.raises(NotSupported):
            await robot.start_patrol()
        assert robot.link.commands_sent == sent


async def test_robot_http_is_there_on_http_links_only() -> None:
    async with robot_on_http() as (_, robot, _face):
        assert isinstance(robot.http, HttpPart)
    async with galileo.connect("sim://?speed=40") as robot:
        assert robot.http is None
        with pytest.raises(InvalidArgument, match=r"robot\.http is None"):
            await robot.send(ApiCall("GET", "/map/image"))
        assert robot.link.commands_sent == 0


async def test_rest_calls_go_through_the_links_one_writer() -> None:
    async with robot_on_http() as (_, robot, face):
        await robot.wait_until(lambda s: True, timeout=WAIT)
        sent = robot.link.commands_sent
        link = robot._link  # type: ignore[attr-defined]
        assert await link.send(ApiCall("GET", "/map/image")) == ["sim", "floor2"]
        await http_of(robot).say("hi")
        assert robot.link.commands_sent == sent + 2
        assert face.spoken == ["hi"]


async def test_robot_http_is_bound_to_the_robots_loop_and_closes_with_it() -> None:
    async with robot_on_http() as (_, robot, face):
        http = http_of(robot)
        await robot.wait_until(lambda s: True, timeout=WAIT)
        before = face.requests

        async def elsewhere() -> None:
            await http.maps()

        with pytest.raises(galileo.WrongEventLoop):
            await asyncio.to_thread(asyncio.run, elsewhere())
        assert face.requests == before
    with pytest.raises(galileo.GalileoConnectionError, match="closed"):
        await http.maps()
    assert face.requests == before


async def test_robot_http_on_a_lost_link_sends_nothing() -> None:
    async with robot_on_http({"reconnect": False}) as (_, robot, face):
        await robot.wait_until(lambda s: True, timeout=WAIT)
        async with asyncio.timeout(WAIT):
            events = robot.events()
            for request, _outbox in list(face.sockets.values()):
                request.transport.abort()
            async for event in events:
                if isinstance(event, ConnectionLostEvent):
                    break
        before = face.requests
        with pytest.raises(galileo.ConnectionLost, match=r"maps\(\): nothing was sent"):
            await http_of(robot).maps()
        assert face.requests == before


async def test_send_returns_the_rest_answer_and_refusals_queue_nothing() -> None:
    async with robot_on_http() as (_, robot, _face):
        link = robot._link
        assert link.capabilities.rest_api
        assert link.capabilities.pose_goals
        answer = await link.send(ApiCall("GET", "/system/info"))
        assert answer["info"] == (await http_of(robot).info()).raw["info"]
        where = await link.send(ApiCall("GET", "/navigation/current_path"))
        assert (where["map"], where["path"]) == astuple(await http_of(robot).current_map())
        sent = robot.link.commands_sent
        for refused in (RawCommand(b"x"), RotateTo(90)):
            with pytest.raises(NotSupported, match="no HTTP API form"):
                link.enqueue(refused)
            with pytest.raises(NotSupported, match="no HTTP API form"):
                await link.send(refused)
        assert not link.queue.entries
        assert robot.link.commands_sent == sent


async def test_a_cancelled_sender_leaves_its_call_to_finish() -> None:
    held = asyncio.Event()
    release = asyncio.Event()
    bodies: list[dict[str, Any]] = []

    async def status(request: web.Request) -> web.WebSocketResponse:
        ws = web.WebSocketResponse()
        await ws.prepare(request)
        await ws.send_str(json.dumps({"navStatus": 1, "power": 24.0, "targetNumID": -1}))
        async for _ in ws:
            pass
        return ws

    async def speed(request: web.Request) -> web.Response:
        bodies.append(await request.json())
        held.set()
        await release.wait()
        return web.json_response({"result": True})

    routes = [web.get("/galileo/status", status), web.put("/api/v1/system/speed", speed)]
    async with bare_server(routes) as port:
        url = f"http://127.0.0.1:{port}?ws_port={port}"
        async with galileo.connect(url, stale_timeout=None) as robot:
            link = robot._link
            sender = asyncio.create_task(link.send(Velocity(0.1, 0.0)))
            await asyncio.wait_for(held.wait(), WAIT)
            sender.cancel()
            with pytest.raises(asyncio.CancelledError):
                await sender
            release.set()
            # Written behind the first call, which finished: the writer counted both.
            assert await asyncio.wait_for(link.send(Stop()), WAIT) == {"result": True}
            assert link.stats.commands_sent == 2
            assert link.channel.failed_calls == 0  # type: ignore[attr-defined]
        assert [body["speed_x"] for body in bodies] == [0.1, 0.0]


# --- error paths -----------------------------------------------------------------------------


async def test_401_names_endpoint_and_status() -> None:
    async with Simulator(speed=SPEED) as sim:
        face = await sim.serve_http(token_check=True)
        port, ws_port = face.address[1], face.ws_address[1]
        with pytest.raises(HttpError) as info:
            await galileo.connect(f"http://127.0.0.1:{port}?ws_port={ws_port}", reconnect=False)
        assert info.value.status == 401
        url = f"http://admin:admin@127.0.0.1:{port}?ws_port={ws_port}"
        async with galileo.connect(url) as robot:
            assert await http_of(robot).maps() == ["sim", "floor2"]


#: Set when a bare server closes: its silent handlers then answer.
RELEASE: list[asyncio.Event] = []


async def silent(request: web.Request) -> web.Response:
    """A handler that answers only when its server closes."""
    await RELEASE[-1].wait()
    return web.Response(status=503)


async def test_a_token_option_and_no_secret_in_logs(caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.DEBUG)
    async with Simulator(speed=SPEED) as sim:
        face = await sim.serve_http(token_check=True)
        port, ws_port = face.address[1], face.ws_address[1]
        face.tokens.add("t0ken-5ecret")
        url = f"http://127.0.0.1:{port}?ws_port={ws_port}"
        async with galileo.connect(url, token="t0ken-5ecret") as robot:
            assert await http_of(robot).maps() == ["sim", "floor2"]
            assert "t0ken-5ecret" not in repr(robot._link)  # type: ignore[attr-defined]
            face.tokens.clear()  # revoked: the failure is logged and raised without it
            with pytest.raises(HttpError) as info:
                await robot.stop()
            assert "t0ken-5ecret" not in str(info.value)
        login = f"http://admin:admin@127.0.0.1:{port}?ws_port={ws_port}"
        async with galileo.connect(login) as robot:
            assert await http_of(robot).current_map()
    for secret in ("t0ken-5ecret", "admin:admin", "password=admin"):
        assert secret not in caplog.text
    assert "***" in caplog.text or "HTTP 401" in caplog.text


@contextlib.asynccontextmanager
async def bare_server(routes: list[web.RouteDef]) -> AsyncIterator[int]:
    RELEASE.append(asyncio.Event())
    app = web.Application()
    app.add_routes(routes)
    runner = web.AppRunner(app, handle_signals=False, access_log=None)
    await runner.setup()
    site = web.TCPSite(runner, "127.0.0.1", 0)
    await site.start()
    try:
        yield site._server.sockets[0].getsockname()[1]  # type: ignore[union-attr]
    finally:
        RELEASE.pop().set()
        await runner.cleanup()


async def test_a_refused_command_raises_its_http_error_to_the_caller() -> None:
    async with robot_on_http() as (_, robot, face):
        await navigating(robot)
        face.token_check = True  # the token is revoked: every REST call is refused
        with pytest.raises(HttpError) as info:
            await robot.stop()
        assert (info.value.status, info.value.endpoint) == (401, "/system/speed")
        with pytest.raises(HttpError) as info:
            await robot.goto(0, timeout=WAIT)
        assert info.value.endpoint == "/navigation/move_to_index"
        # stop()'s cancel (no goal shown: sent in case) and its GET /task (running task chains)
        # failed too, without failing stop().
        assert robot._link.channel.failed_calls == 4  # type: ignore[attr-defined]


async def test_404_500_and_timeouts_are_http_errors() -> None:
    async with robot_on_http() as (_, robot, _face):
        api = robot._link.channel.api  # type: ignore[attr-defined]
        with pytest.raises(HttpError) as info:
            await api.call("GET", "/no/such")
        assert (info.value.status, info.value.endpoint) == (404, "/no/such")

    async def broken(request: web.Request) -> web.Response:
        raise web.HTTPInternalServerError()

    routes = [web.get("/api/v1/map/image", broken), web.get("/api/v1/system/info", silent)]
    async with bare_server(routes) as port:
        api = HttpApi(f"http://127.0.0.1:{port}", timeout=0.3)
        try:
            with pytest.raises(HttpError) as info:
                await api.call("GET", "/map/image")
            assert info.value.status == 500
            assert "/map/image" in str(info.value)
            with pytest.raises(HttpError, match="no answer within") as info:
                await api.call("GET", "/system/info")
            assert info.value.status is None
        finally:
            await api.close()


async def test_a_server_that_never_answers_the_websocket() -> None:
    async with bare_server([web.get("/galileo/status", silent)]) as port:
        url = f"http://127.0.0.1:{port}?ws_port={port}"
        with pytest.raises(HttpError) as info:
            await galileo.connect(url, reconnect=False, connect_timeout=0.3)
        assert info.value.endpoint == "/galileo/status"


async def test_a_dropped_websocket_reconnects(caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.WARNING)
    async with robot_on_http() as (_, robot, face):
        await robot.wait_until(lambda s: True, timeout=WAIT)
        seen: list[type] = []
        async with asyncio.timeout(WAIT):
            events = robot.events()
            for request, _outbox in list(face.sockets.values()):
                request.transport.abort()
            async for event in events:
                seen.append(type(event))
                if isinstance(event, ConnectionRestored):
                    break
        assert ConnectionLostEvent in seen
        assert robot.link.reconnects >= 1


async def test_the_link_pings_on_its_own_timer_while_statuses_stream() -> None:
    # aiohttp's heartbeat is re-armed by every received frame: at 30 Hz it would never ping.
    async with robot_on_http(robot_options={"ping_interval": 0.05}) as (_, robot, face):
        await robot.wait_until(lambda s: True, timeout=WAIT)
        async with asyncio.timeout(WAIT):
            while face.pings < 3:
                face.pinged.clear()
                await face.pinged.wait()
        assert robot.link.frames > 0


async def test_a_websocket_gone_silent_is_stale_then_reopened() -> None:
    opened = 0

    async def status(request: web.Request) -> web.WebSocketResponse:
        nonlocal opened
        opened += 1
        ws = web.WebSocketResponse()
        await ws.prepare(request)
        await ws.send_str(json.dumps({"navStatus": 1, "power": 24.0, "targetNumID": -1}))
        async for _ in ws:  # then silent, the connection kept open
            pass
        return ws

    async with bare_server([web.get("/galileo/status", status)]) as port:
        url = f"http://127.0.0.1:{port}?ws_port={port}"
        options = {"stale_timeout": 0.2, "stale_reconnect": 2.0, "reconnect_initial": 0.05}
        async with galileo.connect(url, **options) as robot:
            seen: list[type] = []
            async with asyncio.timeout(WAIT):
                async for event in robot.events():
                    seen.append(type(event))
                    if isinstance(event, ConnectionRestored):
                        break
            assert seen[0] is LinkStaleEvent
            assert opened >= 2
            assert robot.link.reconnects >= 1


async def test_speeds_do_not_pile_up_behind_a_slow_call() -> None:
    held = asyncio.Event()
    release = asyncio.Event()
    stopped = asyncio.Event()
    bodies: list[dict[str, Any]] = []

    async def status(request: web.Request) -> web.WebSocketResponse:
        ws = web.WebSocketResponse()
        await ws.prepare(request)
        await ws.send_str(json.dumps({"navStatus": 1, "power": 24.0, "targetNumID": -1}))
        async for _ in ws:
            pass
        return ws

    async def speed(request: web.Request) -> web.Response:
        bodies.append(await request.json())
        held.set()
        if bodies[-1]["speed_x"] == 0:
            stopped.set()
        await release.wait()
        return web.json_response({"result": True})

    routes = [web.get("/galileo/status", status), web.put("/api/v1/system/speed", speed)]
    async with bare_server(routes) as port:
        url = f"http://127.0.0.1:{port}?ws_port={port}"
        async with galileo.connect(url, stale_timeout=None) as robot:
            # The drive keep-alive's path: enqueue, nobody waits, each speed superseded by
            # the next speed or stop queued behind it (the Link drops it, unwritten).
            link = robot._link
            replaced_by = (Velocity, Stop)
            link.enqueue(Velocity(0.3, 0.0), superseded_by=replaced_by)
            await held.wait()
            dropped = [
                link.enqueue(Velocity(linear, 0.0), superseded_by=replaced_by)
                for linear in (0.2, 0.1, 0.05)
            ]
            stop = link.enqueue(Stop())
            release.set()
            assert await asyncio.wait_for(stop, WAIT)  # written (answered) behind them
            await asyncio.wait_for(stopped.wait(), WAIT)
            assert [future.result() for future in dropped] == [False, False, False]
        assert [body["speed_x"] for body in bodies] == [0.3, 0.0]


def test_cli_sim_http_and_status_goto_over_http() -> None:
    sim = subprocess.Popen(
        [sys.executable, "-m", "galileo_async", "sim", "--http", "0", "--speed", "20"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert sim.stdout is not None
        url = sim.stdout.readline().strip()
        assert url.startswith("http://127.0.0.1:")
        cli = [sys.executable, "-m", "galileo_async", "-p", url]
        result = subprocess.run(
            [*cli, "status", "--json"], capture_output=True, text=True, timeout=WAIT * 3
        )
        assert result.returncode == 0, result.stderr
        assert '"layout": "ros"' in result.stdout
        login = url.replace("http://", "http://admin:admin@")
        result = subprocess.run(
            [sys.executable, "-m", "galileo_async", "-p", login, "status", "--json"],
            capture_output=True,
            text=True,
            timeout=WAIT * 3,
        )
        assert result.returncode == 0, result.stderr  # a token is fetched, then used
        assert '"port": "http://admin:***@127.0.0.1:' in result.stdout
        assert "admin:admin" not in result.stdout + result.stderr
        result = subprocess.run(
            [*cli, "nav", "start"], capture_output=True, text=True, timeout=WAIT * 3
        )
        assert result.returncode == 0, result.stdout + result.stderr
        result = subprocess.run([*cli, "goto", "0"], capture_output=True, text=True, timeout=60)
        assert result.returncode == 0, result.stdout + result.stderr
    finally:
        sim.terminate()
        sim.communicate(timeout=WAIT)


async def test_closing_the_robot_ends_a_running_goto_pose() -> None:
    async with robot_on_http() as (_, robot, _face):
        await navigating(robot)
        going = asyncio.ensure_future(http_of(robot).goto_pose(40.0, 0.0, timeout=WAIT))
        await robot.wait_until(lambda s: s.target_num_id == -2 and s.goal_active, timeout=WAIT)
        await robot.close()
        with pytest.raises(galileo.GalileoConnectionError):
            await going


async def test_mapping_over_http() -> None:
    async with robot_on_http() as (sim, robot, _face):
        await robot.wait_until(lambda s: True, timeout=WAIT)
        await robot.start_mapping(timeout=WAIT)
        assert sim.state.status.mapping
        await robot.stop_mapping(timeout=WAIT)
        assert not sim.state.status.mapping
