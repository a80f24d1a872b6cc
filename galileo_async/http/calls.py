"""The REST call of each command an http:// link carries: one table, ``REST_CALLS``."""

from __future__ import annotations

from collections.abc import Awaitable, Callable
from typing import Any

from ..errors import NotSupported
from ..protocol import ApiCall
from ..protocol import commands as cmd
from ..protocol.velocity import PoseGoal, Velocity
from .client import HttpApi

__all__ = ["REST_CALLS", "RestCall", "rest_call"]


#: Makes one command's call: ``(command, api, last task id) -> answer``.
RestCall = Callable[[Any, HttpApi, "str | None"], Awaitable[Any]]


def _fixed(method: str, endpoint: str) -> RestCall:
    """The call of a command without parameters."""

    def call(command: cmd.Command, api: HttpApi, task_id: str | None) -> Awaitable[Any]:
        return api.call(method, endpoint)

    return call


def _speed(command: Velocity | cmd.Stop, api: HttpApi, task_id: str | None) -> Awaitable[Any]:
    linear, angular = (
        (command.linear, command.angular) if isinstance(command, Velocity) else (0.0, 0.0)
    )
    body = {"speed_x": linear, "speed_y": 0.0, "speed_angle": angular}
    return api.call("PUT", "/system/speed", body=body)


def _pose_goal(command: PoseGoal, api: HttpApi, task_id: str | None) -> Awaitable[Any]:
    body = {"x": command.x, "y": command.y, "theta": command.theta}
    return api.call("POST", "/navigation/start_nav_task", body=body)


def _goto(command: cmd.Goto, api: HttpApi, task_id: str | None) -> Awaitable[Any]:
    return api.call("GET", "/navigation/move_to_index", {"index": command.target_id})


def _task_call(verb: str) -> RestCall:
    """Pause or resume the last task a call returned, else the one that is working."""

    async def call(command: cmd.Command, api: HttpApi, task_id: str | None) -> Any:
        if task_id is None:  # a task someone else started: the one that works
            tasks = await api.call("GET", "/task")
            working = [t for t in tasks if isinstance(t, dict) and t.get("state") == "WORKING"]
            if not working:
                return None
            task_id = str(working[0].get("id"))
        return await api.call("GET", f"/task/{verb}", {"id": task_id})

    return call


async def _start_navigation(command: cmd.Command, api: HttpApi, task_id: str | None) -> Any:
    current = await api.call("GET", "/navigation/current_path")
    where = current if isinstance(current, dict) else {}
    return await api.call(
        "GET", "/navigation/start", {"map": where.get("map", ""), "path": where.get("path", "")}
    )


def _api_call(command: ApiCall, api: HttpApi, task_id: str | None) -> Awaitable[Any]:
    params = None if command.params is None else dict(command.params)
    body = None if command.body is None else dict(command.body)
    return api.call(command.method, command.endpoint, params, body)


#: Each command type the HTTP API carries and the call that carries it (a subclass without
#: an entry takes its nearest base's: a PoseGoal is not a Goto here, it has its own).
REST_CALLS: dict[type[cmd.Command], RestCall] = {
    cmd.Cancel: _fixed("GET", "/navigation/stop_nav_task"),
    cmd.StopNavigation: _fixed("GET", "/navigation/stop"),
    cmd.StopPatrol: _fixed("DELETE", "/navigation/loop_task"),
    cmd.StartCharging: _fixed("GET", "/navigation/go_charge"),
    cmd.StopCharging: _fixed("GET", "/navigation/stop_charge"),
    cmd.ShutdownHost: _fixed("GET", "/system/shutdown"),
    cmd.StartMapping: _fixed("GET", "/map/start"),
    cmd.StopMapping: _fixed("GET", "/map/stop"),
    cmd.StartNavigation: _start_navigation,
    cmd.Pause: _task_call("pause"),
    cmd.Resume: _task_call("resume"),
    cmd.Goto: _goto,
    PoseGoal: _pose_goal,
    Velocity: _speed,
    cmd.Stop: _speed,
    ApiCall: _api_call,
}


def rest_call(command: cmd.Command) -> RestCall:
    """The call that carries ``command`` (not made yet); NotSupported if none does."""
    for kind in type(command).__mro__:
        call = REST_CALLS.get(kind)
        if call is not None:
            return call
    raise NotSupported(
        f"{command} has no HTTP API form: use a serial, socket://, udp:// or ros:// link"
    )
