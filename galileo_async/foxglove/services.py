"""One robot's services for Foxglove's Service Call panel, through the public Robot API.

The SDK calls a handler on a thread of its own: the handler parses the JSON request there,
hands the call to the event loop and waits for its answer at most SERVICE_TIMEOUT seconds
(then the call is cancelled on the loop). A goto or goto_point answers once the robot
accepted the goal, not when it arrives; the goal then runs on the robot, followed on the
events channel (a goal never shown accepted within accept_timeout is cancelled, as goto's
own exit would). A stop is the Robot's stop(): it supersedes every goal still waiting to be
sent, a Foxglove goto's too; a goto called after it is a new command and moves the robot.
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import json
import math
from collections.abc import Callable, Coroutine
from typing import TYPE_CHECKING, Any

import foxglove

from ..events import Event, GoalAccepted
from .schemas import SERVICE_REQUESTS, service_schema

if TYPE_CHECKING:
    from ..robot import Robot

__all__ = ["SERVICES", "SERVICE_TIMEOUT", "Calls", "ServiceError", "robot_services"]

#: The services of each robot, ``/name/<service>``.
SERVICES = tuple(SERVICE_REQUESTS)
#: Seconds a service call may take on the loop before it is cancelled and fails.
SERVICE_TIMEOUT = 30.0

_Json = dict[str, Any]


class ServiceError(Exception):
    """A service call failed: the message is what the caller's panel shows."""


class Calls:
    """The service calls in flight on the loop: ended, and refused, once the server closes."""

    def __init__(self, loop: asyncio.AbstractEventLoop) -> None:
        self.loop = loop
        self.closing = False
        self._tasks: set[asyncio.Task[Any]] = set()

    def run(self, make: Callable[[], Coroutine[Any, Any, _Json]], timeout: float) -> bytes:
        """On the SDK's thread: run ``make()`` on the loop; its JSON answer, or ServiceError."""
        if self.closing:
            raise ServiceError("the server is closing")
        try:
            future = asyncio.run_coroutine_threadsafe(self._on_loop(make), self.loop)
        except RuntimeError:  # the loop is closed
            raise ServiceError("the server is closing") from None
        try:
            answer = future.result(timeout)
        except concurrent.futures.TimeoutError:
            future.cancel()
            raise ServiceError(f"no answer within {timeout:g} s; the call was cancelled") from None
        except concurrent.futures.CancelledError:
            raise ServiceError("cancelled: the server is closing") from None
        return json.dumps(answer).encode()

    async def _on_loop(self, make: Callable[[], Coroutine[Any, Any, _Json]]) -> _Json:
        if self.closing:  # checked on the loop: no call starts after close() began
            raise ServiceError("the server is closing")
        task = asyncio.ensure_future(make())
        self._tasks.add(task)
        try:
            return await task
        finally:
            self._tasks.discard(task)

    async def close(self) -> None:
        """Refuse new calls, cancel the ones running and wait for them."""
        self.closing = True
        tasks = list(self._tasks)
        for task in tasks:
            task.cancel()
        if tasks:
            await asyncio.wait(tasks)


def _request(name: str, payload: bytes) -> _Json:
    """The JSON request of service ``name``, checked; ServiceError says what is wrong."""
    text = payload.decode("utf-8", "replace").strip() or "{}"
    try:
        request = json.loads(text)
    except ValueError as exc:
        raise ServiceError(f"{name}: the request is not JSON ({exc})") from None
    if not isinstance(request, dict):
        raise ServiceError(f"{name}: the request must be a JSON object, got {text!r}")
    fields = SERVICE_REQUESTS[name]["properties"]
    extra = sorted(set(request) - set(fields))
    if extra:
        raise ServiceError(f"{name}: unknown field(s) {', '.join(extra)}; it takes {_takes(name)}")
    for key in SERVICE_REQUESTS[name].get("required", ()):
        if key not in request:
            raise ServiceError(f"{name}: missing {key!r}; it takes {_takes(name)}")
    for key, value in request.items():
        if fields[key]["type"] == "integer":
            if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= 255:
                raise ServiceError(f"{name}: {key} must be a target id 0..255, got {value!r}")
        elif (
            isinstance(value, bool)
            or not isinstance(value, (int, float))
            or not math.isfinite(value)
        ):
            raise ServiceError(f"{name}: {key} must be a finite number of metres, got {value!r}")
    return request


def _takes(name: str) -> str:
    fields = list(SERVICE_REQUESTS[name]["properties"])
    return "{" + ", ".join(f'"{key}": …' for key in fields) + "}" if fields else "{}"


async def _until_accepted(
    robot: Robot, goal: Coroutine[Any, Any, object], target: int | None = None
) -> _Json:
    """Run ``goal`` (a goto with cancel_on_exit False) until the robot accepts it or it ends.

    ``target``: the goal id to wait for (None: the first goal accepted). Once accepted the
    goto is left (nothing is sent): the goal runs on the robot.
    """
    loop = asyncio.get_running_loop()
    accepted: asyncio.Future[int | None] = loop.create_future()

    def listen(event: Event) -> None:
        if not isinstance(event, GoalAccepted) or accepted.done():
            return
        if target is None or event.target_id == target:
            accepted.set_result(event.target_id)

    robot.add_event_listener(listen)
    task = asyncio.ensure_future(goal)
    try:
        either: list[asyncio.Future[Any]] = [task, accepted]
        await asyncio.wait(either, return_when=asyncio.FIRST_COMPLETED)
        if accepted.done():
            return {"accepted": True, "target": accepted.result(), "arrived": False}
        # Ended before its acceptance showed: it raises (a goal written and never accepted
        # was cancelled by goto's own exit), or it arrived.
        result = task.result()
        return {"accepted": True, "target": getattr(result, "target_id", None), "arrived": True}
    finally:
        robot.remove_event_listener(listen)
        accepted.cancel()
        if not task.done():
            task.cancel()
            await asyncio.wait({task})
        if not task.cancelled():
            task.exception()  # retrieved: an error after acceptance is the events channel's


def _call(robot: Robot, name: str, request: _Json) -> Coroutine[Any, Any, _Json]:
    """The coroutine that performs service ``name`` on ``robot``."""

    async def goto() -> _Json:
        target = request["target"]
        return await _until_accepted(robot, robot.goto(target, cancel_on_exit=False), target)

    async def goto_point() -> _Json:
        x, y = float(request["x"]), float(request["y"])
        return await _until_accepted(robot, robot.goto_point(x, y, cancel_on_exit=False))

    async def stop() -> _Json:
        await robot.stop()
        return {"stopped": True}

    async def cancel() -> _Json:
        await robot.cancel()
        return {"cancelled": True}

    async def pause() -> _Json:
        await robot.pause()
        return {"paused": True}

    async def resume() -> _Json:
        await robot.resume()
        return {"resumed": True}

    async def dock() -> _Json:
        charge = await robot.start_charging()
        return {"charge_status": charge.name}

    calls = {
        "goto": goto, "goto_point": goto_point, "stop": stop, "cancel": cancel,
        "pause": pause, "resume": resume, "dock": dock,
    }  # fmt: skip
    return calls[name]()


def robot_services(
    name: str, robot: Robot, calls: Calls, *, timeout: float = SERVICE_TIMEOUT
) -> list[foxglove.Service]:
    """The services ``/name/goto`` … ``/name/dock`` of ``robot``."""

    def handler(service: str) -> Callable[[foxglove.ServiceRequest], bytes]:
        def handle(call: foxglove.ServiceRequest) -> bytes:
            request = _request(service, call.payload)
            return calls.run(lambda: _call(robot, service, request), timeout)

        return handle

    return [
        foxglove.Service(
            f"/{name}/{service}",
            schema=foxglove.ServiceSchema(
                f"galileo_async.{service}",
                request=foxglove.MessageSchema(
                    encoding="json",
                    schema=foxglove.Schema(
                        name=f"galileo_async.{service}.Request",
                        encoding="jsonschema",
                        data=service_schema(service),
                    ),
                ),
            ),
            handler=handler(service),
        )
        for service in SERVICES
    ]
