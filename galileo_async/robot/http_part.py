"""robot.http: what only the robot's HTTP API can do (maps, targets, firmware, speech, poses).

A Robot has this part on an ``http://`` or ``https://`` link only (``robot.http`` is None on
every other link). Each call goes through Operations (its checks and the link's one writer).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol

from .._checks import check_number
from ..errors import InvalidArgument
from ..protocol import ApiCall, Goto, PoseGoal
from .goal import GoalResult
from .operations import Operations
from .runtime import ROBOT_DEFAULT, RobotDefault

__all__ = ["HttpPart", "MapPath", "NavPoint", "RobotInfo"]


@dataclass(frozen=True)
class MapPath:
    """A map and one of its paths (the path holds the saved targets)."""

    map: str
    path: str


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

    __slots__ = ("_goals", "_ops")

    def __init__(self, ops: Operations, goals: _Goals) -> None:
        self._ops = ops
        self._goals = goals

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
