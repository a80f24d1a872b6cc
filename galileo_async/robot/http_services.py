"""What only the HTTP API can do: maps, targets, battery %, firmware, speech, pose goals, speed.

Each method raises NotSupported on a link that is not ``http://`` / ``https://``.
"""

from __future__ import annotations

import asyncio
import math
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

from .._checks import check_number, check_timeout
from ..errors import GalileoTimeout, GoalCancelled, InvalidArgument, NotSupported, TaskFailed
from ..state.store import StatusStore
from ..transports import Link
from .goal import GoalResult
from .operations import Operations
from .runtime import finish_shielded

__all__ = ["DEFAULT_TASK_POLL", "HttpServices", "MapPath", "NavPoint", "RobotInfo"]

#: Seconds between two reads of a running task's state (GET /task?id=).
DEFAULT_TASK_POLL = 0.1
_ENDED = ("COMPLETE", "CANCELLED", "ERROR")


@runtime_checkable
class _Api(Protocol):
    """The REST calls of an http:// channel (HttpChannel.call)."""

    async def call(
        self,
        method: str,
        endpoint: str,
        params: dict[str, Any] | None = None,
        body: dict[str, Any] | None = None,
    ) -> Any: ...


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


class HttpServices:
    """Robot methods over the vendor's REST API; NotSupported on other links."""

    _link: Link
    _store: StatusStore
    _ops: Operations

    def _api(self, what: str) -> _Api:
        """The link's REST API; WrongEventLoop off the Robot's loop, NotSupported off http://."""
        self._ops.ensure_open()
        channel = self._link.channel
        if not (self._link.capabilities.rest_api and isinstance(channel, _Api)):
            raise NotSupported(f"{what} needs the robot's HTTP API: connect with http://host:3546")
        return channel

    @property
    def has_http_api(self) -> bool:
        """True on an ``http://`` / ``https://`` link: the methods here are supported."""
        return self._link.capabilities.rest_api

    async def maps(self) -> list[str]:
        """The names of the maps saved on the robot (GET /map/image)."""
        names = await self._api("maps()").call("GET", "/map/image")
        return [str(name) for name in names]

    async def current_map(self) -> MapPath:
        """The map and path navigation uses (GET /navigation/current_path)."""
        answer = await self._api("current_map()").call("GET", "/navigation/current_path")
        return MapPath(str(answer["map"]), str(answer["path"]))

    async def switch_map(self, name: str, path: str | None = None) -> MapPath:
        """Switch to map ``name`` (``path`` None: its default) without restarting navigation."""
        api = self._api("switch_map()")
        if not isinstance(name, str) or not name or not (path is None or isinstance(path, str)):
            raise InvalidArgument("switch_map: name (and path) must be non-empty strings")
        params = {"map": name} if path is None else {"map": name, "path": path}
        answer = await api.call("GET", "/navigation/reload", params)
        return MapPath(str(answer.get("map", name)), str(answer.get("path", path or "")))

    async def targets(self) -> list[NavPoint]:
        """The saved targets of the current map and path, in index order (nav_points)."""
        api = self._api("targets()")
        where = await api.call("GET", "/navigation/current_path")
        params = {"map_name": where["map"], "path_name": where["path"]}
        answer = await api.call("GET", "/navigation/nav_points", params)
        points = []
        for line in str(answer.get("path_data", "")).splitlines():
            fields = line.split()
            if len(fields) >= 4:
                points.append(NavPoint(float(fields[0]), float(fields[1]), float(fields[3])))
        return points

    async def info(self) -> RobotInfo:
        """Firmware version, code name and battery (GET /system/info)."""
        answer = await self._api("info()").call("GET", "/system/info")
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
        api = self._api("say()")
        if not isinstance(text, str) or not text:
            raise InvalidArgument("say: text must be a non-empty string")
        await api.call("GET", "/system/tts", {"text": text})

    async def navigation_speed(self) -> float:
        """The fastest the robot drives while navigating, m/s (GET /system/config)."""
        answer = await self._api("navigation_speed()").call("GET", "/system/config")
        return float(answer["navigation_speed"])

    async def set_navigation_speed(self, mps: float) -> float:
        """Drive goals no faster than ``mps`` m/s (> 0; POST /system/config); the value set."""
        api = self._api("set_navigation_speed()")
        check_number("mps", mps, low=0.0, low_open=True)
        body = {"navigation_speed": float(mps)}
        answer = await api.call("POST", "/system/config", body=body)
        return float(answer.get("navigation_speed", mps))

    async def goto_pose(
        self,
        x: float,
        y: float,
        theta: float = 0.0,
        *,
        timeout: float | None = 600.0,
        poll_interval: float = DEFAULT_TASK_POLL,
    ) -> GoalResult:
        """Go to (x, y) m facing ``theta`` rad as a nav task; return when it is COMPLETE.

        TaskFailed (a GoalError, with the task's ``state``) when it ends CANCELLED or ERROR;
        GalileoTimeout after ``timeout`` s. A call cancelled or timed out stops the task
        (GET /navigation/stop_nav_task) before it ends; stop() ends it at once with
        GoalCancelled (``cancelled_by`` "stop()"), its own cancel stopping the task.
        """
        api = self._api("goto_pose()")
        for name, value in (("x", x), ("y", y), ("theta", theta)):
            check_number(name, value)
        check_timeout("timeout", timeout)
        check_timeout("poll_interval", poll_interval)
        body = {"x": float(x), "y": float(y), "theta": float(theta)}
        loop = asyncio.get_running_loop()
        started = loop.time()
        task = await api.call("POST", "/navigation/start_nav_task", body=body)
        task_id = str(task["id"])

        async def ended() -> Any:
            answer = task
            while answer.get("state") not in _ENDED:
                await asyncio.sleep(poll_interval)
                answer = await api.call("GET", "/task", {"id": task_id})
            return answer

        async def stop_task() -> None:
            await api.call("GET", "/navigation/stop_nav_task")

        halted: asyncio.Future[Any] = loop.create_future()

        def halt(by: str) -> None:
            if not halted.done():
                halted.set_exception(
                    GoalCancelled(
                        f"goto_pose({x}, {y}, {theta}): task {task_id} was cancelled by {by}",
                        target_id=-2,
                        status=self._store.status,
                        cancelled_by=by,
                    )
                )

        unregister = self._ops.moving(halt, task=task_id)
        polling = asyncio.ensure_future(asyncio.wait_for(ended(), timeout))
        try:
            await asyncio.wait((polling, halted), return_when=asyncio.FIRST_COMPLETED)
            if halted.done():  # stop() sent the cancel itself
                polling.cancel()
                await asyncio.gather(polling, return_exceptions=True)
                await halted
            task = await polling
        except GoalCancelled:
            raise
        except BaseException as exc:
            polling.cancel()
            stopping = asyncio.ensure_future(stop_task())
            await finish_shielded(stopping, "goto_pose: stopping the task")
            if isinstance(exc, asyncio.TimeoutError):
                raise GalileoTimeout(
                    f"goto_pose: task {task_id} did not end within {timeout} s",
                    self._store.status,
                ) from None
            raise
        finally:
            unregister()
            if not halted.done():
                halted.cancel()
        status = self._store.status
        if task["state"] != "COMPLETE" or status is None:
            raise TaskFailed(
                f"goto_pose({x}, {y}, {theta}): task {task_id} ended {task['state']}",
                state=str(task["state"]), task_id=task_id, status=status,
            )  # fmt: skip
        distance = None
        if status.current_pose_x is not None and status.current_pose_y is not None:
            distance = math.hypot(status.current_pose_x - x, status.current_pose_y - y)
        return GoalResult(-2, distance, loop.time() - started, status)
