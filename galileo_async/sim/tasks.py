"""The simulated robot's task chains: the HTTP API's /task and /action (docs/protocol.md §5.5).

Sans-IO: a TaskEngine holds the tasks as the vendor's JSON and runs them on the model's
clock, one step per batch of frames (``step``); the HTTP face routes requests to it and
makes callback_action's request through the ``callback`` hook.
"""

from __future__ import annotations

import math
import uuid
from collections.abc import Callable
from typing import Any

from ..protocol import commands as cmd
from .config import FRAME_RATE
from .motion import turn_toward, wrap_angle
from .robot_model import FRAME_TIME, RobotModel
from .states import ACTIVE, CHARGE_FREE, CHARGED, CHARGING, FREE, PAUSED, WORKING

__all__ = [
    "ACTION_TYPES",
    "DONE",
    "CallbackHook",
    "TaskEngine",
    "TaskError",
]

#: Task and action states, as the vendor spells them (WAITTING sic).
WAITTING, RUNNING, HELD = "WAITTING", "WORKING", "PAUSED"
COMPLETE, CANCELLED, FAILED = "COMPLETE", "CANCELLED", "ERROR"
#: States a task or action ends in.
DONE = (COMPLETE, CANCELLED, FAILED)

#: Each action type the simulator runs, and its parameters: name -> (kind, default).
#: A default of None makes the parameter required.
ACTION_TYPES: dict[str, dict[str, tuple[str, Any]]] = {
    "nav_action": {"x": ("number", None), "y": ("number", None), "theta": ("number", 0.0)},
    "sleep_action": {"wait_time": ("number", None)},
    "charge_action": {"x": ("number", None), "y": ("number", None), "theta": ("number", 0.0)},
    "local_move_action": {
        "distance": ("number", 0.0), "angle": ("number", 0.0), "method": ("method", 0),
    },
    "callback_action": {"url": ("url", None), "method": ("verb", "POST"), "data": ("data", None)},
    "wait_req_action": {},
}  # fmt: skip
#: Action types of the vendor's API that the simulator refuses (they need a scheduler).
_NOT_SIMULATED = ("upload_map_action", "download_map_action")
_VERBS = ("GET", "POST", "PUT", "DELETE", "PATCH")
#: A local move ends this close to its heading (rad) and distance (m).
_ANGLE_TOLERANCE = 0.005
_DISTANCE_TOLERANCE = 0.002

#: Makes a callback_action's request: ``(action, done)``, ``done(None)`` on success, else
#: ``done(why)``; returns what cancels the request.
CallbackHook = Callable[[dict[str, Any], Callable[[str | None], None]], Callable[[], None]]


class TaskError(ValueError):
    """A request the task API refuses: ``status`` 404 (no such id) or 400 (bad input)."""

    def __init__(self, message: str, status: int = 400) -> None:
        super().__init__(message)
        self.status = status


def _number(name: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, str)):
        raise TaskError(f"{name} must be a number, got {value!r}")
    try:
        number = float(value)
    except ValueError:
        raise TaskError(f"{name} must be a number, got {value!r}") from None
    if not math.isfinite(number):
        raise TaskError(f"{name} must be finite, got {value!r}")
    return number


def _param(kind: str, name: str, value: Any) -> Any:
    if kind == "number":
        return _number(name, value)
    if kind == "method":
        if value not in (0, 1, "0", "1") or isinstance(value, bool):
            raise TaskError(f"method must be 0 (none) or 1 (lidar), got {value!r}")
        return int(value)
    if kind == "url":
        if not isinstance(value, str) or not value.startswith(("http://", "https://")):
            raise TaskError(f"url must be an http:// or https:// URL, got {value!r}")
        return value
    if kind == "verb":
        if not isinstance(value, str) or value.upper() not in _VERBS:
            raise TaskError(f"method must be one of {', '.join(_VERBS)}, got {value!r}")
        return value.upper()
    return value  # data: any JSON


def flag(value: Any) -> bool:
    """A loop_flag from JSON or a query string ("true"/"false", "1"/"0")."""
    if isinstance(value, bool):
        return value
    text = str(value).strip().lower()
    if text in ("true", "1"):
        return True
    if text in ("false", "0"):
        return False
    raise TaskError(f"loop_flag must be true or false, got {value!r}")


def _action(body: dict[str, Any], *, keep: dict[str, Any] | None = None) -> dict[str, Any]:
    """A new action's JSON from a request: its type's parameters checked, state WAITTING."""
    kind = body.get("type", None if keep is None else keep["type"])
    if kind in _NOT_SIMULATED:
        raise TaskError(f"{kind} needs the vendor's scheduling server: not simulated")
    params = ACTION_TYPES.get(kind) if isinstance(kind, str) else None
    if params is None:
        raise TaskError(f"unknown action type {kind!r}: one of {', '.join(ACTION_TYPES)}")
    action: dict[str, Any] = {"type": kind}
    for name, (what, default) in params.items():
        value = body.get(name, default if keep is None else keep.get(name, default))
        if value is None and what != "data":
            raise TaskError(f"{kind} needs {name}")
        action[name] = _param(what, name, value) if value is not None else None
    if kind == "callback_action" and action["data"] is None:
        action["data"] = {}
    if kind == "sleep_action" and action["wait_time"] < 0:
        raise TaskError(f"wait_time must be >= 0, got {action['wait_time']}")
    action["state"] = WAITTING
    action["id"] = str(uuid.uuid4()) if keep is None else keep["id"]
    return action


class TaskEngine:
    """The robot's tasks by id, and the one task that runs (WORKING or PAUSED) at a time.

    A task runs its sub_tasks in order; an action that ends ERROR or CANCELLED ends the
    task so; the last one COMPLETE counts a pass (loop_count) and, with loop_flag, starts
    the chain again. nav_action is a pose goal (the /navigation pose goal's machinery),
    sleep_action waits simulated seconds, charge_action docks at its pose, local_move_action
    turns by angle then drives distance, callback_action calls ``callback``,
    wait_req_action waits for ``release_wait``.
    """

    def __init__(
        self,
        model: RobotModel,
        execute: Callable[[list[cmd.Command]], None] | None = None,
        *,
        callback: CallbackHook | None = None,
    ) -> None:
        self.model = model
        self._execute = execute or self._submit
        self.callback = callback
        #: Every task, by id, as the vendor's JSON (the same dicts the API answers).
        self.tasks: dict[str, dict[str, Any]] = {}
        #: Why each action that ended ERROR did (not in the vendor's JSON).
        self.errors: dict[str, str] = {}
        self.running: dict[str, Any] | None = None
        self._index = 0
        self._state: dict[str, Any] = {}  # the running action's own progress
        self._cancel_callout: Callable[[], None] | None = None

    def _submit(self, commands: list[cmd.Command]) -> None:
        for command in commands:
            self.model.submit(command)

    # --- the API --------------------------------------------------------------------

    def get(self, task_id: str) -> dict[str, Any]:
        """The task ``task_id``; TaskError 404 if there is none."""
        task = self.tasks.get(str(task_id))
        if task is None:
            raise TaskError(f"no task {task_id!r}", 404)
        return task

    def create(self, body: dict[str, Any]) -> dict[str, Any]:
        """POST /task: a WAITTING task of ``sub_tasks`` (actions, or {"id"} of existing ones)."""
        name = str(body.get("name", "task"))
        sub_tasks = self._sub_tasks(body.get("sub_tasks", []))
        task: dict[str, Any] = {
            "name": name, "loop_flag": flag(body.get("loop_flag", False)),
            "id": str(uuid.uuid4()), "state": WAITTING, "sub_tasks": sub_tasks,
            "progress": 0, "current_task": None, "loop_count": 0,
        }  # fmt: skip
        self.tasks[task["id"]] = task
        return task

    def update(self, body: dict[str, Any]) -> dict[str, Any]:
        """PUT /task: a new name, loop_flag or sub_tasks of a task that does not run."""
        task = self._idle(body)
        sub_tasks = self._sub_tasks(body["sub_tasks"]) if "sub_tasks" in body else None
        loop = flag(body["loop_flag"]) if "loop_flag" in body else task["loop_flag"]
        task["name"] = str(body.get("name", task["name"]))
        task["loop_flag"] = loop
        if sub_tasks is not None:
            task["sub_tasks"] = sub_tasks
        return task

    def delete(self, task_id: str) -> dict[str, Any]:
        """DELETE /task: stopped first if it runs."""
        task = self.get(task_id)
        self.stop(task_id)
        del self.tasks[task["id"]]
        return {"status": "OK"}

    def start(self, task_id: str) -> dict[str, Any]:
        """Run the task from its first action (again, if it ended); another running is stopped."""
        task = self.get(task_id)
        if task["state"] in (RUNNING, HELD):
            return task
        if self.running is not None:
            self._end(CANCELLED)
        task["loop_count"] = 0
        self.running = task
        self._begin_pass(task)
        self.step()
        return task

    def pause(self, task_id: str) -> dict[str, Any]:
        """A WORKING task: PAUSED, its action held where it is (a goal paused, wheels stopped)."""
        task = self.get(task_id)
        if task is self.running and task["state"] == RUNNING:
            task["state"] = HELD
            action = task["current_task"]
            if action is not None and action["state"] == RUNNING:
                action["state"] = HELD
                self._hold(action)
        return task

    def resume(self, task_id: str) -> dict[str, Any]:
        """A PAUSED task: WORKING again, its action from where it was held."""
        task = self.get(task_id)
        if task is self.running and task["state"] == HELD:
            task["state"] = RUNNING
            action = task["current_task"]
            if action is not None and action["state"] == HELD:
                action["state"] = RUNNING
                self._unhold(action)
            self.step()
        return task

    def stop(self, task_id: str) -> dict[str, Any]:
        """A task not ended: CANCELLED, its action cancelled and the robot stopped."""
        task = self.get(task_id)
        if task is self.running:
            self._end(CANCELLED)
        elif task["state"] not in DONE:
            task["state"] = CANCELLED
        return task

    def set_loop(self, task_id: str, value: Any) -> dict[str, Any]:
        """GET /task/loop: set loop_flag (it counts from the end of the current pass)."""
        task = self.get(task_id)
        task["loop_flag"] = flag(value)
        return task

    def release_wait(self) -> dict[str, Any] | None:
        """GET /action/update_wait_req: the wait_req_action that waits ends COMPLETE; or None."""
        task = self.running
        action = None if task is None else task["current_task"]
        if action is None or action["type"] != "wait_req_action" or action["state"] in DONE:
            return None
        self._state["released"] = True
        if task is not None and task["state"] == RUNNING:
            self.step()
        released: dict[str, Any] = action
        return released

    # --- actions by id --------------------------------------------------------------

    def actions(self) -> list[dict[str, Any]]:
        """Every action of every task."""
        return [a for task in self.tasks.values() for a in task["sub_tasks"]]

    def action(self, action_id: str) -> tuple[dict[str, Any], dict[str, Any]]:
        """The action ``action_id`` and its task; TaskError 404 if there is none."""
        for task in self.tasks.values():
            for action in task["sub_tasks"]:
                if action["id"] == str(action_id):
                    return action, task
        raise TaskError(f"no action {action_id!r}", 404)

    def add_action(self, body: dict[str, Any]) -> dict[str, Any]:
        """POST /action: into task ``task_id`` (not running), else a new "auto task"; the task."""
        action = _action(body)
        if "task_id" in body:
            task = self._idle({"id": body["task_id"]})
        else:
            task = self.create({"name": "auto task"})
        task["sub_tasks"].append(action)
        return task

    def update_action(self, body: dict[str, Any]) -> dict[str, Any]:
        """PUT /action: new parameters of an action whose task does not run; the action."""
        action, task = self.action(body["id"])
        self._idle({"id": task["id"]})
        changed = _action(body, keep=action)
        action.clear()
        action.update(changed)
        return action

    def delete_action(self, action_id: str) -> dict[str, Any]:
        """DELETE /action: out of its task, which must not run."""
        action, task = self.action(action_id)
        self._idle({"id": task["id"]})
        task["sub_tasks"].remove(action)
        return {"status": "OK"}

    # --- running --------------------------------------------------------------------

    def preempt(self) -> None:
        """A goal or docking given by hand: the running task is CANCELLED, its action halted."""
        if self.running is not None:
            self._end(CANCELLED)

    def close(self) -> None:
        """Stop the running task (the simulated robot goes away)."""
        if self.running is not None:
            self._end(CANCELLED)

    def send_statuses(self, frames: list[Any]) -> None:
        """A batch of frames went by: step the running task."""
        self.step()

    def step(self) -> None:
        """Advance the running task to the model's present: end actions, start the next."""
        # Bounded: a looping chain of actions that end at once goes on at the next step.
        for _ in range(len(self.running["sub_tasks"]) + 2 if self.running is not None else 0):
            task = self.running
            if task is None or task["state"] != RUNNING:
                return
            action = task["current_task"]
            if action["state"] == WAITTING:
                action["state"] = RUNNING
                self._state = {}
                self._begin(action)
            ending = self._follow(action) if action["state"] == RUNNING else action["state"]
            if ending is None:
                return
            self._finish(task, action, ending)

    def _finish(self, task: dict[str, Any], action: dict[str, Any], ending: str) -> None:
        if ending != COMPLETE:
            if action["type"] == "local_move_action":
                self.model.set_speed(0.0, 0.0)
            action["state"] = ending
            self._end(ending, halt=False)
            return
        action["state"] = ending
        self._index += 1
        subs = task["sub_tasks"]
        task["progress"] = round(100 * self._index / len(subs))
        if self._index < len(subs):
            task["current_task"] = subs[self._index]
            return
        task["loop_count"] += 1
        if task["loop_flag"]:
            self._begin_pass(task)
        else:
            task["state"] = COMPLETE
            self.running = None

    def _begin_pass(self, task: dict[str, Any]) -> None:
        self._index = 0
        for action in task["sub_tasks"]:
            action["state"] = WAITTING
        task["progress"] = 0
        if not task["sub_tasks"]:  # nothing to do: done at once, even when looping
            task["state"], task["progress"], self.running = COMPLETE, 100, None
            return
        task["state"] = RUNNING
        task["current_task"] = task["sub_tasks"][0]

    def _end(self, state: str, *, halt: bool = True) -> None:
        """The running task ends ``state``; its action, if not ended, too (halted first)."""
        task = self.running
        assert task is not None
        action = task["current_task"]
        if action is not None and action["state"] not in DONE:
            if halt and action["state"] != WAITTING:
                self._halt(action)
            action["state"] = state
        task["state"] = state
        self.running = None
        self._state = {}

    # --- each action: begin, follow (its ending or None), hold, unhold, halt ----------

    def _begin(self, action: dict[str, Any]) -> None:
        kind, model, now = action["type"], self.model, self.model.time
        if kind == "nav_action":
            model.goto_pose(action["x"], action["y"])
            if not (model.target_num_id == -2 and model.target_status == WORKING):
                self._state["refused"] = "navigation is not open, or the goal was refused"
        elif kind == "sleep_action":
            self._state["until"] = now + action["wait_time"]
        elif kind == "charge_action":
            model.dock = (action["x"], action["y"])
            if model.charge_status not in (CHARGING, CHARGED):
                self._execute([cmd.StartCharging()])
        elif kind == "local_move_action":
            self._state.update(heading=wrap_angle(model.theta + action["angle"]), moved=0.0)
        elif kind == "callback_action":
            if self.callback is None:
                self._state["result"] = "no callback hook: nothing can be called"
            else:
                self._state["result"] = ""  # "": under way
                self._cancel_callout = self.callback(dict(action), self._called(action["id"]))

    def _called(self, action_id: str) -> Callable[[str | None], None]:
        def done(error: str | None) -> None:
            task = self.running
            action = None if task is None else task["current_task"]
            if action is None or action["id"] != action_id or action["state"] in DONE:
                return  # stopped meanwhile
            self._cancel_callout = None
            self._state["result"] = error
            if task is not None and task["state"] == RUNNING:
                self.step()

        return done

    def _follow(self, action: dict[str, Any]) -> str | None:
        kind, model, state = action["type"], self.model, self._state
        if kind == "nav_action":
            if "refused" in state:
                return self._fail(action, state["refused"])
            if model.target_num_id != -2:
                return self._fail(action, "another goal replaced the task's goal")
            if model.target_status in ACTIVE:
                return None
            if model.target_status == FREE and model.target_distance <= (
                model.config.arrival_distance
            ):
                return COMPLETE
            return self._fail(action, "the goal ended away from the pose")
        if kind == "sleep_action":
            return COMPLETE if model.time + 1e-9 >= state["until"] else None
        if kind == "charge_action":
            if model.charge_status in (CHARGING, CHARGED):
                return COMPLETE
            if model.charge_status == CHARGE_FREE or model.charge_status == 5:
                return self._fail(action, "docking stopped or failed")
            return None
        if kind == "local_move_action":
            return self._local_move(action)
        if kind == "callback_action":
            result = state["result"]
            if result == "":
                return None
            return COMPLETE if result is None else self._fail(action, result)
        return COMPLETE if state.get("released") else None  # wait_req_action

    def _fail(self, action: dict[str, Any], why: str) -> str:
        self.errors[action["id"]] = why
        return FAILED

    def _local_move(self, action: dict[str, Any]) -> str | None:
        model, state = self.model, self._state
        if "start" not in state:
            w, turned = turn_toward(model.theta, state["heading"], model.config.max_turn_rate,
                                    FRAME_TIME)  # fmt: skip
            if not turned or abs(wrap_angle(state["heading"] - model.theta)) > _ANGLE_TOLERANCE:
                model.set_speed(0.0, w)
                return None
            state["start"] = (model.x, model.y)
        start, distance = state["start"], action["distance"]
        left = abs(distance) - math.hypot(model.x - start[0], model.y - start[1])
        if left <= _DISTANCE_TOLERANCE:
            model.set_speed(0.0, 0.0)
            return COMPLETE
        speed = min(model.navigation_speed, left * FRAME_RATE)
        model.set_speed(math.copysign(speed, distance), 0.0)
        return None

    def _hold(self, action: dict[str, Any]) -> None:
        kind = action["type"]
        if kind == "nav_action" and self.model.target_status == WORKING:
            self._execute([cmd.Pause()])
        elif kind == "sleep_action":
            self._state["left"] = self._state["until"] - self.model.time
        elif kind == "local_move_action":
            self.model.set_speed(0.0, 0.0)

    def _unhold(self, action: dict[str, Any]) -> None:
        kind = action["type"]
        if kind == "nav_action" and self.model.target_status == PAUSED:
            self._execute([cmd.Resume()])
        elif kind == "sleep_action":
            self._state["until"] = self.model.time + self._state.pop("left")

    def _halt(self, action: dict[str, Any]) -> None:
        kind = action["type"]
        if kind == "nav_action" and self.model.target_num_id == -2:
            if self.model.target_status in ACTIVE:
                self._execute([cmd.Cancel()])
        elif kind == "charge_action" and self.model.charge_status not in (CHARGING, CHARGED):
            self._execute([cmd.StopCharging()])
        elif kind == "local_move_action":
            self.model.set_speed(0.0, 0.0)
        elif kind == "callback_action" and self._cancel_callout is not None:
            cancel, self._cancel_callout = self._cancel_callout, None
            cancel()

    # --- helpers --------------------------------------------------------------------

    def _idle(self, body: dict[str, Any]) -> dict[str, Any]:
        task = self.get(body["id"])
        if task["state"] in (RUNNING, HELD):
            raise TaskError(f"task {task['id']} runs: stop it first")
        return task

    def _sub_tasks(self, items: Any) -> list[dict[str, Any]]:
        if not isinstance(items, list):
            raise TaskError("sub_tasks must be a list of actions")
        actions = []
        for item in items:
            if not isinstance(item, dict):
                raise TaskError(f"a sub_task must be an object, got {item!r}")
            if "type" not in item and "id" in item:  # an existing action, copied
                known, _ = self.action(item["id"])
                item = {k: v for k, v in known.items() if k not in ("id", "state")}
            actions.append(_action(item))
        return actions
