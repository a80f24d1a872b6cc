"""robot.http: what only the robot's HTTP API can do (maps, targets, firmware, speech, poses).

A Robot has this part on an ``http://`` or ``https://`` link only (``robot.http`` is None on
every other link). Each call goes through Operations (its checks and the link's one writer).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

from .._checks import check_number
from ..errors import InvalidArgument, OperationFailed
from ..protocol import ApiCall, Goto, PoseGoal
from .goal import GoalResult
from .operations import Operations
from .runtime import ROBOT_DEFAULT, RobotDefault
from .task_chain import Action, Task, action_json

__all__ = ["HttpPart", "MapImage", "MapPath", "NavPoint", "RobotInfo"]

_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


@dataclass(frozen=True)
class MapPath:
    """A map and one of its paths (the path holds the saved targets)."""

    map: str
    path: str


@dataclass(frozen=True)
class MapImage:
    """A map as a PNG: ``width`` x ``height`` pixels of ``resolution`` m each.

    ``origin`` is (x m, y m, yaw rad) of the lower left pixel on the map, as the robot gives
    it; the PNG's first row is the top of the map (docs/protocol.md §5.3).
    """

    origin: tuple[float, float, float]
    width: int
    height: int
    resolution: float
    png: bytes = field(repr=False)


@dataclass(frozen=True)
class NavPoint:
    """A saved target: metres and radians."""

    x: float
    y: float
    theta: float


@dataclass(frozen=True)
class RobotInfo:
    """GET /system/info: firmware ``version`` and ``code_name`` (None before 4.5 / 5.1)."""

    version: str | None
    code_name: str | None
    battery_percent: int | None
    raw: dict[str, Any]


class _Goals(Protocol):
    """The Robot's one goal path (Robot._goto): checks, then the GoalRunner."""

    async def __call__(
        self,
        command: Goto,
        timeout: float | RobotDefault | None,
        accept_timeout: float | None,
        progress_timeout: float | RobotDefault | None,
        cancel_on_exit: bool,
    ) -> GoalResult: ...


class HttpPart:
    """``robot.http``: the vendor's REST API calls, each sent as an ApiCall; goals by pose."""

    __slots__ = ("_chains", "_goals", "_ops")

    def __init__(self, ops: Operations, goals: _Goals) -> None:
        self._ops = ops
        self._goals = goals
        self._chains: set[str] = set()

    @property
    def started_tasks(self) -> frozenset[str]:
        """Ids of the task chains this part started or resumed and has not seen end."""
        return frozenset(self._chains)

    def __repr__(self) -> str:
        return f"<HttpPart of {self._ops.link!r}>"

    async def _call(
        self,
        what: str,
        method: str,
        endpoint: str,
        params: dict[str, Any] | None = None,
        body: dict[str, Any] | None = None,
    ) -> Any:
        return await self._ops.ask(ApiCall(method, endpoint, params, body), what=what)

    async def maps(self) -> list[str]:
        """The names of the maps saved on the robot (GET /map/image)."""
        names = await self._call("maps()", "GET", "/map/image")
        return [str(name) for name in names]

    async def current_map(self) -> MapPath:
        """The map and path navigation uses (GET /navigation/current_path)."""
        answer = await self._call("current_map()", "GET", "/navigation/current_path")
        return MapPath(str(answer["map"]), str(answer["path"]))

    async def switch_map(self, name: str, path: str | None = None) -> MapPath:
        """Switch to map ``name`` (``path`` None: its default) without restarting navigation."""
        if not isinstance(name, str) or not name or not (path is None or isinstance(path, str)):
            raise InvalidArgument("switch_map: name (and path) must be non-empty strings")
        params = {"map": name} if path is None else {"map": name, "path": path}
        answer = await self._call("switch_map()", "GET", "/navigation/reload", params)
        return MapPath(str(answer.get("map", name)), str(answer.get("path", path or "")))

    async def map_image(self) -> MapImage:
        """The current map and its PNG (GET /map/current_map_image, then its map_image).

        OperationFailed when the robot has no map loaded or answers other than a PNG; each
        request within the link's ``request_timeout`` (HttpTimeout).
        """
        answer = await self._call("map_image()", "GET", "/map/current_map_image")
        params = answer.get("map_params") if isinstance(answer, dict) else None
        if not isinstance(params, dict) or str(answer.get("status", "OK")).upper() != "OK":
            status = answer.get("status") if isinstance(answer, dict) else answer
            raise OperationFailed(f"map_image(): the robot has no map loaded ({status!r})", None)
        try:
            x, y, yaw = (float(v) for v in params["origin"])
            width, height = int(params["width"]), int(params["height"])
            resolution = float(params["resolution"])
        except (KeyError, TypeError, ValueError):
            raise OperationFailed(
                f"map_image(): map_params not understood: {params!r}", None
            ) from None
        where = str(answer.get("map_image") or "")
        # A path below the API's (the vendor's answer); anything else: the documented one.
        endpoint = where[7:] if where.startswith("/api/v1/") else "/map/current_map_png"
        png = _png("map_image()", await self._call("map_image()", "GET", endpoint))
        return MapImage((x, y, yaw), width, height, resolution, png)

    async def map_png(self, name: str) -> bytes:
        """The PNG of saved map ``name`` (GET /navigation/map_png); OperationFailed if no PNG."""
        if not isinstance(name, str) or not name:
            raise InvalidArgument("map_png: name must be a non-empty string")
        answer = await self._call("map_png()", "GET", "/navigation/map_png", {"name": name})
        return _png("map_png()", answer)

    async def targets(self, map: str | None = None, path: str | None = None) -> list[NavPoint]:
        """The saved targets of a map's path (None: the current map, path), in index order."""
        if map is None or path is None:
            where = await self._call("targets()", "GET", "/navigation/current_path")
            map, path = map or str(where["map"]), path or str(where["path"])
        params = {"map_name": map, "path_name": path}
        answer = await self._call("targets()", "GET", "/navigation/nav_points", params)
        points = []
        for line in str(answer.get("path_data", "")).splitlines():
            fields = line.split()
            if len(fields) >= 4:
                points.append(NavPoint(float(fields[0]), float(fields[1]), float(fields[3])))
        return points

    async def charge_pose(self) -> NavPoint:
        """The charger's pose on the current map: metres, radians (GET /navigation/charge_pose)."""
        answer = await self._call("charge_pose()", "GET", "/navigation/charge_pose")
        try:
            return NavPoint(float(answer["x"]), float(answer["y"]), float(answer.get("theta", 0.0)))
        except (KeyError, TypeError, ValueError, AttributeError):
            raise OperationFailed(f"charge_pose(): no pose in {answer!r}", None) from None

    async def info(self) -> RobotInfo:
        """Firmware version, code name and battery (GET /system/info)."""
        answer = await self._call("info()", "GET", "/system/info")
        about = answer.get("info") or {}
        battery = answer.get("battery")
        return RobotInfo(
            about.get("version"),
            about.get("code_name"),
            int(battery) if isinstance(battery, (int, float)) else None,
            answer,
        )

    async def battery_percent(self) -> int | None:
        """The battery charge in percent (GET /system/info), None if the robot does not say."""
        return (await self.info()).battery_percent

    async def say(self, text: str) -> None:
        """Speak ``text`` on the robot (GET /system/tts)."""
        if not isinstance(text, str) or not text:
            raise InvalidArgument("say: text must be a non-empty string")
        await self._call("say()", "GET", "/system/tts", {"text": text})

    async def navigation_speed(self) -> float:
        """The fastest the robot drives while navigating, m/s (GET /system/config)."""
        answer = await self._call("navigation_speed()", "GET", "/system/config")
        return float(answer["navigation_speed"])

    async def set_navigation_speed(self, mps: float) -> float:
        """Drive goals no faster than ``mps`` m/s (> 0; POST /system/config); the value set."""
        check_number("mps", mps, low=0.0, low_open=True)
        body = {"navigation_speed": float(mps)}
        answer = await self._call("set_navigation_speed()", "POST", "/system/config", body=body)
        return float(answer.get("navigation_speed", mps))

    async def goto_pose(
        self,
        x: float,
        y: float,
        theta: float = 0.0,
        *,
        timeout: float | RobotDefault | None = ROBOT_DEFAULT,
        accept_timeout: float | None = None,
        progress_timeout: float | RobotDefault | None = ROBOT_DEFAULT,
        cancel_on_exit: bool = True,
    ) -> GoalResult:
        """Go to (x, y) m facing ``theta`` rad as one nav task, followed as goal -2.

        The goal path of Robot.goto (the same checks, options, errors and events): NotReady
        inside a drive block or with navigation closed, nothing sent; GoalCancelled when
        cancelled, preempted or stopped; GoalAborted when the planner gives up away from
        the pose; GoalStalled, AcceptTimeout and OperationTimeout as goto.
        """
        command = PoseGoal(
            x=check_number("x", x), y=check_number("y", y), theta=check_number("theta", theta)
        )
        return await self._goals(command, timeout, accept_timeout, progress_timeout, cancel_on_exit)

    # --- task chains (docs/protocol.md §5.5) ----------------------------------------------

    async def _task(self, what: str, endpoint: str, params: dict[str, Any]) -> Task:
        answer = await self._call(what, "GET", endpoint, params)
        task = Task.model_validate(answer)
        if task.ended:
            self._chains.discard(task.id)
        return task

    async def create_task(
        self, name: str, sub_tasks: Sequence[Action | Mapping[str, Any]], loop_flag: bool = False
    ) -> Task:
        """A task of ``sub_tasks`` run in order (POST /task), WAITTING until start_task().

        Each action a model (NavAction, SleepAction, …) or its JSON; InvalidArgument, with
        nothing sent, for a bad name, action or flag. ``loop_flag``: run again after each pass.
        """
        if not isinstance(name, str) or not name:
            raise InvalidArgument(f"create_task: name must be a non-empty string, got {name!r}")
        if isinstance(sub_tasks, (str, bytes, Mapping)) or not isinstance(sub_tasks, Sequence):
            raise InvalidArgument("create_task: sub_tasks must be a sequence of actions")
        if not isinstance(loop_flag, bool):
            raise InvalidArgument(f"create_task: loop_flag must be a bool, got {loop_flag!r}")
        actions = [action_json(a, f"create_task: sub_tasks[{i}]") for i, a in enumerate(sub_tasks)]
        body = {"name": name, "sub_tasks": actions, "loop_flag": loop_flag}
        return Task.model_validate(await self._call("create_task()", "POST", "/task", body=body))

    async def get_task(self, task_id: str) -> Task:
        """The task ``task_id`` as the robot reports it now (GET /task)."""
        return await self._task("get_task()", "/task", {"id": _task_id(task_id)})

    async def list_tasks(self) -> list[Task]:
        """Every task the robot holds (GET /task), nav tasks of goals among them."""
        answer = await self._call("list_tasks()", "GET", "/task")
        return [Task.model_validate(task) for task in answer]

    async def start_task(self, task_id: str) -> Task:
        """Run the task from its first action (GET /task/start); stop() stops it."""
        task_id = _task_id(task_id)
        self._chains.add(task_id)  # before the call: a stop() meanwhile must know it
        return await self._task("start_task()", "/task/start", {"id": task_id})

    async def pause_task(self, task_id: str) -> Task:
        """Pause the running task where it is (GET /task/pause): a goal paused, wheels stopped."""
        return await self._task("pause_task()", "/task/pause", {"id": _task_id(task_id)})

    async def resume_task(self, task_id: str) -> Task:
        """Resume a paused task (GET /task/resume)."""
        task_id = _task_id(task_id)
        self._chains.add(task_id)
        return await self._task("resume_task()", "/task/resume", {"id": task_id})

    async def stop_task(self, task_id: str) -> Task:
        """Cancel the task (GET /task/stop): its action ends and the robot stops."""
        return await self._task("stop_task()", "/task/stop", {"id": _task_id(task_id)})

    async def set_task_loop(self, task_id: str, loop: bool) -> Task:
        """Run the task again after each pass, or not (GET /task/loop)."""
        if not isinstance(loop, bool):
            raise InvalidArgument(f"set_task_loop: loop must be a bool, got {loop!r}")
        params = {"id": _task_id(task_id), "loop_flag": "true" if loop else "false"}
        return await self._task("set_task_loop()", "/task/loop", params)

    async def delete_task(self, task_id: str) -> None:
        """Delete the task (DELETE /task); the robot stops it first if it runs."""
        task_id = _task_id(task_id)
        await self._call("delete_task()", "DELETE", "/task", {"id": task_id})
        self._chains.discard(task_id)

    async def release_wait(self) -> bool:
        """End the wait_req_action that waits (GET /action/update_wait_req); False if none did."""
        answer = await self._call("release_wait()", "GET", "/action/update_wait_req")
        return isinstance(answer, dict) and bool(answer)


def _task_id(task_id: str) -> str:
    if not isinstance(task_id, str) or not task_id:
        raise InvalidArgument(f"task id must be a non-empty string, got {task_id!r}")
    return task_id


def _png(what: str, answer: Any) -> bytes:
    if not isinstance(answer, bytes) or not answer.startswith(_PNG_SIGNATURE):
        shown = answer[:40] if isinstance(answer, (bytes, str)) else answer
        raise OperationFailed(f"{what}: the robot answered no PNG: {shown!r}", None)
    return answer
