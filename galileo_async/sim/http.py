"""The simulator's HTTP face: the vendor's REST API (/api/v1) and WebSocket status (http.md).

Needs aiohttp (the extra ``http``); loaded only by Simulator.serve_http.
"""

from __future__ import annotations

import asyncio
import json
import math
import ssl
import uuid
from collections.abc import Awaitable, Callable
from typing import Any

import aiohttp
from aiohttp import WSMsgType, web

from ..protocol import commands as cmd
from ..protocol.names import ROS_FIELD_NAMES
from .config import FRAME_RATE
from .device import SimDevice
from .map_image import sim_map
from .robot_model import WIRE_FIELDS, WireValues
from .tasks import TaskEngine, TaskError

__all__ = ["MAPS", "VERSION", "HttpFace"]

#: What /system/info reports as the firmware.
VERSION = {"version": "5.1.0", "code_name": "galileo-sim"}
#: The simulated robot's maps and each map's paths; navigation starts on the first.
MAPS: dict[str, tuple[str, ...]] = {"sim": ("path1",), "floor2": ("path1", "path2")}
#: What /system/info reports besides the battery: sensor rates (Hz) and the robot.
_RATES = {"camera_rgb": 30, "camera_depth": 30, "odom": 50, "imu": 100, "camera_processed": 30}
_INFO = {**VERSION, "id": "SIM", "mac": "00:00:00:00:00:00", "port": 3546}
#: The JSON name of each wire value, in WIRE_FIELDS order.
_JSON_NAMES = tuple({v: k for k, v in ROS_FIELD_NAMES.items()}[f] for f in WIRE_FIELDS)
_ID, _STATUS, _DISTANCE = (WIRE_FIELDS.index(f) for f in ("target_num_id", "target_status",
                                                          "target_distance"))  # fmt: skip
#: Statuses a WebSocket may lag behind before the oldest are dropped.
_OUTBOX = 64
_Handler = Callable[[web.Request], Awaitable[web.StreamResponse]]


def _task(name: str, action: dict[str, Any]) -> dict[str, Any]:
    action = {"state": "WAITTING", "result": "", "progress": 0, **action, "id": str(uuid.uuid4())}
    return {
        "name": name, "loop_flag": False, "id": str(uuid.uuid4()), "state": "WORKING",
        "sub_tasks": [action], "progress": 0, "current_task": action,
    }  # fmt: skip


def _refused(exc: TaskError) -> web.HTTPException:
    """The answer to a refused task request: 404 or 400, the reason as its phrase and JSON."""
    reason = str(exc).encode("ascii", "replace").decode()[:200]
    kind = web.HTTPNotFound if exc.status == 404 else web.HTTPBadRequest
    text = json.dumps({"status": "error", "description": str(exc)})
    return kind(reason=reason, text=text, content_type="application/json")


class HttpFace:
    """REST on one port, /galileo/status as JSON on a WebSocket port; tasks follow the model.

    A navigation task is WORKING while the model shows its goal running (index, or -2 for a
    pose), COMPLETE when it ends on the target, ERROR when the planner gave up short of it, on
    a goal error or a goal refused, CANCELLED when stopped or replaced. The status shows a
    task as the vendor's does (system_monitor noetic, galileo_status_service.py L251-264,
    L305-317): looked at once every ``task_refresh`` s, until then the goal fields from before
    it. Token checking is off unless ``token_check``. Task chains (/task, /action) run in
    ``engine`` (sim/tasks.py); a callback_action's request gets ``callback_timeout`` s.
    """

    def __init__(
        self,
        device: SimDevice,
        *,
        token_check: bool = False,
        username: str = "admin",
        password: str = "admin",
        ssl_context: ssl.SSLContext | None = None,
    ) -> None:
        self.device = device
        #: Both ports speak TLS (https://, wss://) with this context; None: plain.
        self.ssl_context = ssl_context
        self.token_check = token_check
        self._login = (username, password)
        self.tokens: set[str] = set()
        #: Every task made, by id; the last navigation task and the goal id it waits for.
        self.tasks: dict[str, dict[str, Any]] = {}
        self._nav: tuple[dict[str, Any], int] | None = None
        self.engine = TaskEngine(device.model, device.execute, callback=self._call_out)
        self.callback_timeout = 10.0
        self._callouts: set[asyncio.Task[None]] = set()
        #: Seconds between two looks of the status at the running task (0: every frame).
        self.task_refresh = 1.0
        #: Frames to the next look, the goal fields it saw, and those from before the task.
        self._next_look = 0
        self._view: tuple[int, int, float] | None = None
        self._before: tuple[int, int, float] | None = None
        #: Texts /system/tts was asked to say, and the map and path in use.
        self.spoken: list[str] = []
        self.current = ("sim", "path1")
        #: Whether a map is loaded: when not, /map/current_map_image says so (no map_params).
        self.map_loaded = True
        #: Each open status WebSocket: its request and the statuses it has still to send.
        self.sockets: dict[web.WebSocketResponse, tuple[web.Request, asyncio.Queue[str]]] = {}
        self.requests = 0
        #: WebSocket pings received (the vendor drops a client that does not ping); set at each.
        self.pings = 0
        self.pinged = asyncio.Event()
        self._runners: list[web.AppRunner] = []
        self.address: tuple[str, int] = ("", 0)
        self.ws_address: tuple[str, int] = ("", 0)
        self.closed = False

    async def start(self, host: str, port: int, ws_port: int | None) -> None:
        """Listen: REST on ``port``, the WebSocket on ``ws_port`` (None: port + 1; 0: any)."""
        rest = web.Application(middlewares=[self._auth])
        rest.add_routes([web.route("*", "/api/v1/{tail:.*}", self._rest)])
        sockets = web.Application(middlewares=[self._auth])
        sockets.add_routes([web.get("/galileo/status", self._status_socket)])
        self.address = await self._listen(rest, host, port)
        ws_port = self.address[1] + 1 if ws_port is None else ws_port
        self.ws_address = await self._listen(sockets, host, ws_port)
        self.device.listeners[self] = None  # tasks follow the frames, a WebSocket open or not

    async def _listen(self, app: web.Application, host: str, port: int) -> tuple[str, int]:
        runner = web.AppRunner(app, handle_signals=False, access_log=None)
        await runner.setup()
        self._runners.append(runner)
        site = web.TCPSite(runner, host, port, ssl_context=self.ssl_context)
        await site.start()
        server = site._server  # the one asyncio.Server a TCPSite holds
        assert isinstance(server, asyncio.Server)
        bound: tuple[str, int] = server.sockets[0].getsockname()[:2]
        return bound

    @web.middleware
    async def _auth(self, request: web.Request, handler: _Handler) -> web.StreamResponse:
        self.requests += 1
        if self.closed:
            raise web.HTTPServiceUnavailable()
        token = request.query.get("token")
        if self.token_check and request.path != "/api/v1/token" and token not in self.tokens:
            raise web.HTTPUnauthorized(text='{"status": "token invalid"}')
        return await handler(request)

    # --- REST --------------------------------------------------------------------------

    async def _rest(self, request: web.Request) -> web.StreamResponse:
        route = (request.method, "/" + request.match_info["tail"])
        handler = self._routes().get(route)
        if handler is None:
            raise web.HTTPNotFound()
        query = dict(request.query)
        if request.method in ("POST", "PUT"):
            try:
                body = await request.json()
            except ValueError:
                raise web.HTTPBadRequest() from None
            if isinstance(body, dict):
                query.update(body)
        try:
            answer = handler(query)
        except TaskError as exc:
            raise _refused(exc) from None
        except (KeyError, ValueError, TypeError):
            raise web.HTTPBadRequest() from None
        if isinstance(answer, web.StreamResponse):
            return answer
        return web.json_response(answer)

    def _routes(self) -> dict[tuple[str, str], Callable[[dict[str, Any]], Any]]:
        model = self.device.model
        run, tasks = self._run, self.engine
        return {
            ("GET", "/token"): self._token,
            ("GET", "/system/info"): lambda q: {"battery": self.battery(), **_RATES, "info": _INFO},
            ("GET", "/system/status"): lambda q: {"status": self._system_status()},
            ("PUT", "/system/speed"): lambda q: self._speed(q),
            ("GET", "/system/config"): lambda q: self._config(),
            ("POST", "/system/config"): self._set_config,
            ("GET", "/system/shutdown"): lambda q: run(cmd.ShutdownHost(), {"result": True}),
            ("GET", "/system/tts"): self._say,
            ("GET", "/map/start"): lambda q: run(cmd.StartMapping(), {"result": True}),
            ("GET", "/map/stop"): lambda q: run(cmd.StopMapping(), {"result": True}),
            ("GET", "/map/image"): lambda q: list(MAPS),
            ("GET", "/map/current_map_image"): lambda q: self._map_image(),
            ("GET", "/map/current_map_png"): lambda q: self._map_png(self.map_loaded),
            ("GET", "/navigation/map_png"): lambda q: self._map_png(str(q["name"]) in MAPS),
            ("GET", "/navigation/start"): self._start,
            ("GET", "/navigation/stop"):
                lambda q: run(cmd.StopNavigation(), {"result": True, "description": ""}),
            ("GET", "/navigation/current_path"):
                lambda q: dict(zip(("map", "path"), self.current, strict=True)),
            ("GET", "/navigation/current_map"): lambda q: {"name": self.current[0], "md5sum": ""},
            ("GET", "/navigation/reload"): self._reload,
            ("GET", "/navigation/nav_points"): self._nav_points,
            ("GET", "/navigation/move_to_index"): lambda q: self._goal(
                int(q["index"]), {"type": "nav_action", "index": int(q["index"])}),
            ("POST", "/navigation/start_nav_task"): self._pose_goal,
            ("GET", "/navigation/stop_nav_task"): lambda q: self._stop_task(),
            ("DELETE", "/navigation/loop_task"): lambda q: run(cmd.StopPatrol(), {"result": True}),
            ("GET", "/navigation/go_charge"): lambda q: self._go_charge(),
            ("GET", "/navigation/charge_pose"):
                lambda q: {"x": model.dock[0], "y": model.dock[1], "theta": 0.0},
            ("GET", "/navigation/stop_charge"):
                lambda q: run(cmd.StopCharging(), {"status": "OK", "task": None}),
            ("GET", "/task"): self._get_task,
            ("POST", "/task"): tasks.create,
            ("PUT", "/task"): tasks.update,
            ("DELETE", "/task"): lambda q: tasks.delete(q["id"]),
            ("GET", "/task/start"): self._start_chain,
            ("GET", "/task/pause"): lambda q: self._task_verb(q, cmd.Pause()),
            ("GET", "/task/resume"): lambda q: self._task_verb(q, cmd.Resume()),
            ("GET", "/task/stop"): lambda q: self._task_verb(q, cmd.Cancel()),
            ("GET", "/task/loop"): lambda q: tasks.set_loop(q["id"], q["loop_flag"]),
            ("GET", "/action"):
                lambda q: tasks.action(q["id"])[0] if "id" in q else tasks.actions(),
            ("POST", "/action"): tasks.add_action,
            ("PUT", "/action"): tasks.update_action,
            ("DELETE", "/action"): lambda q: tasks.delete_action(q["id"]),
            ("GET", "/action/update_wait_req"): lambda q: tasks.release_wait(),
            ("GET", "/navigation/pose"):
                lambda q: {"x": model.x, "y": model.y, "angle": math.degrees(model.theta)},
        }  # fmt: skip

    def battery(self) -> int:
        """The battery in percent, from the model's voltage between 20 V and full."""
        config = self.device.config
        share = (self.device.model.power - 20.0) / (config.power_full - 20.0)
        return max(0, min(100, round(share * 100)))

    def _system_status(self) -> str:
        model = self.device.model
        if model.busy:
            return "Busy"
        if model.map_status == 1:
            return "Mapping"
        return "Navigating" if model.nav_status == 1 else "Free"

    def _run(self, command: cmd.Command, answer: Any) -> Any:
        self.device.execute([command])
        return answer

    def _keep(self, task: dict[str, Any]) -> dict[str, Any]:
        self.tasks[task["id"]] = task
        return task

    def _token(self, query: dict[str, Any]) -> Any:
        if (query.get("username"), query.get("password")) != self._login:
            return {"result": False}
        token = uuid.uuid4().hex
        self.tokens.add(token)
        return {"result": True, "token": token}

    def _say(self, query: dict[str, Any]) -> Any:
        self.spoken.append(str(query["text"]))
        return {"status": "OK"}

    def _speed(self, query: dict[str, Any]) -> Any:
        self.device.model.set_speed(float(query["speed_x"]), float(query["speed_angle"]))
        return {"result": True}

    def _config(self) -> dict[str, Any]:
        m = self.device.model
        return {"navigation_speed": m.navigation_speed, "max_control_speed": m.config.max_speed}

    def _set_config(self, body: dict[str, Any]) -> Any:
        if "navigation_speed" in body:
            self.device.model.navigation_speed = float(body["navigation_speed"])
        return self._config()

    def _sim_map(self) -> Any:
        model = self.device.model
        return sim_map([*model.targets, model.dock])

    def _map_image(self) -> Any:
        if not self.map_loaded:
            return {"status": "no map"}
        params = self._sim_map().params()
        return {"status": "OK", "map_params": params, "map_image": "/api/v1/map/current_map_png"}

    def _map_png(self, found: bool) -> web.Response:
        if not found:
            raise web.HTTPNotFound()
        return web.Response(body=self._sim_map().png, content_type="image/png")

    def _start(self, query: dict[str, Any]) -> Any:
        name, path = str(query["map"]), str(query["path"])
        if path not in MAPS.get(name, ()):
            return {"result": False, "description": f"no map {name!r} with path {path!r}"}
        self.current = (name, path)
        return self._run(cmd.StartNavigation(), {"result": True, "description": ""})

    def _reload(self, query: dict[str, Any]) -> Any:
        name = str(query["map"])
        path = str(query.get("path") or MAPS.get(name, ("",))[0])
        if path not in MAPS.get(name, ()):
            raise web.HTTPNotFound()
        self.current = (name, path)
        return {"status": "ok", "map": name, "path": path}

    def _nav_points(self, query: dict[str, Any]) -> Any:
        name = str(query.get("map_name", self.current[0]))
        path = str(query.get("path_name", self.current[1]))
        lines = "".join(f"{x} {y} 0 0 0.1 0.1 0\n" for x, y in self.device.model.targets)
        return {"map_name": name, "path_name": path, "path_data": lines}

    def _goal(self, goal_id: int, action: dict[str, Any]) -> Any:
        self.engine.preempt()  # a goal by hand ends the running task chain
        self._end_nav("CANCELLED")
        task = self._keep(_task("navigation task", action))
        model = self.device.model
        if self._before is None:
            self._before = (model.target_num_id, model.target_status, model.target_distance)
        if goal_id >= 0:
            self.device.execute([cmd.Goto(goal_id)])
        else:
            model.goto_pose(action["x"], action["y"])
        running = model.target_num_id == goal_id and model.target_status in (1, 2)
        if running or (goal_id >= 0 and model.pending):
            task["current_task"]["state"] = "WORKING"
            self._nav = (task, goal_id)
        else:
            task["state"] = task["current_task"]["state"] = "ERROR"
        return task

    def _pose_goal(self, query: dict[str, Any]) -> Any:
        x, y, theta = float(query["x"]), float(query["y"]), float(query["theta"])
        return self._goal(-2, {"type": "nav_action", "x": x, "y": y, "theta": theta})

    def _stop_task(self) -> Any:
        task = self._nav[0] if self._nav is not None else None
        self.device.execute([cmd.Cancel()])
        self._end_nav("CANCELLED")
        return task or {}

    def _go_charge(self) -> Any:
        self.engine.preempt()  # docking by hand ends the running task chain
        task = self._keep(_task("charge task", {"type": "charge_action"}))
        return self._run(cmd.StartCharging(), task)

    def _get_task(self, query: dict[str, Any]) -> Any:
        if "id" not in query:
            return [*self.tasks.values(), *self.engine.tasks.values()]
        task = self.tasks.get(query["id"])
        return self.engine.get(query["id"]) if task is None else task

    def _start_chain(self, query: dict[str, Any]) -> Any:
        task = self.engine.get(query["id"])
        if self._nav is not None and task["state"] not in ("WORKING", "PAUSED"):
            self._stop_task()  # one task at a time: the nav task is cancelled
        return self.engine.start(task["id"])

    def _task_verb(self, query: dict[str, Any], command: cmd.Command) -> Any:
        chains = self.engine
        if query["id"] in chains.tasks:
            verbs: dict[type[cmd.Command], Callable[[str], dict[str, Any]]] = {
                cmd.Pause: chains.pause,
                cmd.Resume: chains.resume,
                cmd.Cancel: chains.stop,
            }
            return verbs[type(command)](query["id"])
        task = self.tasks.get(query["id"])
        if task is None:
            raise TaskError(f"no task {query['id']!r}", 404)
        if isinstance(command, cmd.Cancel):
            self._stop_task()
        elif self._nav is not None and self._nav[0] is task:
            self.device.execute([command])
        return task

    def _end_nav(self, state: str) -> None:
        if self._nav is not None:
            task = self._nav[0]
            task["state"] = task["current_task"]["state"] = state
            task["progress"] = 100 if state == "COMPLETE" else task["progress"]
            self._nav = None

    def _call_out(
        self, action: dict[str, Any], done: Callable[[str | None], None]
    ) -> Callable[[], None]:
        """callback_action's request, as a task of its own; what cancels it."""
        callout = asyncio.create_task(self._request(action, done))
        self._callouts.add(callout)
        callout.add_done_callback(self._callouts.discard)

        def cancel() -> None:
            callout.cancel()

        return cancel

    async def _request(self, action: dict[str, Any], done: Callable[[str | None], None]) -> None:
        """Make the request; an answer of 400 or more, no answer or no connection: failed."""
        method, url, data = action["method"], action["url"], action["data"]
        timeout = aiohttp.ClientTimeout(total=self.callback_timeout)
        error: str | None = None
        try:
            async with (
                aiohttp.ClientSession(timeout=timeout) as session,
                session.request(method, url, json=data) as response,
            ):
                await response.read()
                if response.status >= 400:
                    error = f"{method} {url}: HTTP {response.status}"
        except asyncio.TimeoutError:
            error = f"{method} {url}: no answer within {self.callback_timeout} s"
        except (aiohttp.ClientError, OSError) as exc:
            error = f"{method} {url}: {type(exc).__name__}: {exc}"
        done(error)

    # --- status ------------------------------------------------------------------------

    async def _status_socket(self, request: web.Request) -> web.StreamResponse:
        ws = web.WebSocketResponse(autoping=False)
        await ws.prepare(request)
        outbox: asyncio.Queue[str] = asyncio.Queue(maxsize=_OUTBOX)
        self.sockets[ws] = (request, outbox)
        self.device.listeners[self] = None
        self.device.start()
        sender = asyncio.create_task(self._send(ws, outbox))
        try:
            async for message in ws:  # only pings are read: each is answered and counted
                if message.type is WSMsgType.PING:
                    self.pings += 1
                    self.pinged.set()
                    await ws.pong(message.data)
        finally:
            self.sockets.pop(ws, None)
            sender.cancel()
            await asyncio.wait([sender])
        return ws

    @staticmethod
    async def _send(ws: web.WebSocketResponse, outbox: asyncio.Queue[str]) -> None:
        while True:
            text = await outbox.get()
            try:
                await ws.send_str(text)
            except (ConnectionError, RuntimeError):
                return

    def send_statuses(self, frames: list[WireValues]) -> None:
        """Each frame as one JSON message to every WebSocket; tasks and chains follow it."""
        self.engine.step()
        shown = []
        for values in frames:
            self._follow(values)
            shown.append(self._shown(values))
        if not self.sockets or not frames:
            return
        seq = self.device.model.time_stamp
        for values in shown:
            message = dict(zip(_JSON_NAMES, values, strict=True))
            text = json.dumps({"header": {"seq": seq, "frame_id": ""}, **message})
            for _, outbox in self.sockets.values():
                if outbox.full():  # a slow reader gets the newest statuses
                    outbox.get_nowait()
                outbox.put_nowait(text)

    def _follow(self, values: WireValues) -> None:
        if self._nav is None:
            return
        task, goal_id = self._nav
        shown, status = values[_ID], values[_STATUS]
        if shown == goal_id and status in (1, 2):
            task["current_task"]["state"] = "WORKING"
        elif shown == goal_id and status == 0 and task["current_task"]["state"] == "WORKING":
            # The model lands on the target when it arrives (distance 0): any other end of a
            # goal still shown is the planner giving up, however close it stopped.
            arrived = values[_DISTANCE] <= self.device.config.arrival_distance
            self._end_nav("COMPLETE" if arrived else "ERROR")
        elif shown == goal_id and status in (3, -1):
            self._end_nav("ERROR")
        elif not self.device.model.pending:
            self._end_nav("CANCELLED")

    def _shown(self, values: WireValues) -> WireValues:
        """``values`` with the goal fields the vendor's status shows while HTTP tasks run."""
        self._next_look -= 1
        if self._next_look <= 0:  # it asks for the current nav task at most once a second
            self._next_look = max(1, round(self.task_refresh * FRAME_RATE))
            self._view = None
            if self._nav is None:
                self._before = None  # none: the robot's own fields from now on
            elif self._before is not None:  # its id, WORKING/PAUSED (else as before), distance
                goal_id, status = self._nav[1], values[_STATUS]
                running = values[_ID] == goal_id and status in (1, 2)
                self._view = (goal_id, status if running else self._before[1], values[_DISTANCE])
        fields = self._view or self._before
        if fields is None:
            return values
        shown = list(values)
        shown[_ID], shown[_STATUS], shown[_DISTANCE] = fields
        return tuple(shown)

    def close(self) -> None:
        """Stop serving at once: every WebSocket dropped, every request refused."""
        self.closed = True
        self.device.listeners.pop(self, None)
        self.engine.close()
        for callout in self._callouts:
            callout.cancel()
        for request, _ in list(self.sockets.values()):
            if request.transport is not None:
                request.transport.abort()

    async def aclose(self) -> None:
        """close(), then stop listening."""
        self.close()
        if self._callouts:
            await asyncio.wait(self._callouts)
        for runner in self._runners:
            await runner.cleanup()
        self._runners.clear()
