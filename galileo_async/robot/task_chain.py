"""The robot's task chains over http:// (docs/protocol.md §5.5): actions and the task JSON.

Each action model's ``model_dump()`` is the vendor's JSON of that action; ``Task`` is what
the robot answers about a task. robot.http's task calls take and return these.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, TypeAdapter, ValidationError, field_validator

from ..errors import InvalidArgument

__all__ = [
    "TASK_ENDINGS",
    "Action",
    "CallbackAction",
    "ChargeAction",
    "LocalMoveAction",
    "NavAction",
    "SleepAction",
    "Task",
    "TaskAction",
    "WaitReqAction",
    "action_json",
]

#: The states a task (or an action) ends in; WAITTING (sic), WORKING and PAUSED do not.
TASK_ENDINGS = frozenset({"COMPLETE", "CANCELLED", "ERROR"})

_Number = Annotated[float, Field(allow_inf_nan=False)]


class _Action(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid", strict=True)


class NavAction(_Action):
    """Go to (x, y) m facing ``theta`` rad, as a pose goal."""

    type: Literal["nav_action"] = "nav_action"
    x: _Number
    y: _Number
    theta: _Number = 0.0


class SleepAction(_Action):
    """Wait ``wait_time`` s (>= 0)."""

    type: Literal["sleep_action"] = "sleep_action"
    wait_time: Annotated[float, Field(ge=0.0, allow_inf_nan=False)]


class ChargeAction(_Action):
    """Dock onto the charger at (x, y) m, its front facing ``theta`` rad, and charge."""

    type: Literal["charge_action"] = "charge_action"
    x: _Number
    y: _Number
    theta: _Number = 0.0


class LocalMoveAction(_Action):
    """Turn by ``angle`` rad, then drive ``distance`` m (< 0: backwards); ``method`` 1: lidar."""

    type: Literal["local_move_action"] = "local_move_action"
    distance: _Number = 0.0
    angle: _Number = 0.0
    method: Literal[0, 1] = 0


class CallbackAction(_Action):
    """The robot makes an HTTP request: ``method`` ``url`` with ``data`` as its JSON body."""

    type: Literal["callback_action"] = "callback_action"
    url: str
    method: Literal["GET", "POST", "PUT", "DELETE", "PATCH"] = "POST"
    data: dict[str, Any] = Field(default_factory=dict)

    @field_validator("url")
    @classmethod
    def _http_url(cls, url: str) -> str:
        if not url.startswith(("http://", "https://")) or len(url) <= len("https://"):
            raise ValueError(f"url must be an http:// or https:// URL, got {url!r}")
        return url


class WaitReqAction(_Action):
    """Wait until someone calls GET /action/update_wait_req (robot.http.release_wait())."""

    type: Literal["wait_req_action"] = "wait_req_action"


#: Any action a task chain runs, told apart by its ``type``.
Action = Annotated[
    NavAction | SleepAction | ChargeAction | LocalMoveAction | CallbackAction | WaitReqAction,
    Field(discriminator="type"),
]
_ACTION: TypeAdapter[Action] = TypeAdapter(Action)


def action_json(action: Action | Mapping[str, Any], where: str = "action") -> dict[str, Any]:
    """The vendor's JSON of ``action`` (a model, or its JSON checked); InvalidArgument if bad."""
    if isinstance(action, _Action):
        return action.model_dump()
    if not isinstance(action, Mapping):
        raise InvalidArgument(f"{where} must be an action or a mapping, got {action!r}")
    try:
        return _ACTION.validate_python(dict(action)).model_dump()
    except ValidationError as exc:
        problems = "; ".join(
            f"{'.'.join(str(p) for p in e['loc']) or 'type'}: {e['msg']}" for e in exc.errors()
        )
        raise InvalidArgument(f"{where}: {problems}") from None


class TaskAction(BaseModel):
    """One action of a task as the robot reports it: its parameters are in ``params``."""

    model_config = ConfigDict(frozen=True, extra="allow")

    id: str
    type: str
    state: str = "WAITTING"

    @property
    def params(self) -> dict[str, Any]:
        """The action's own fields (x, y, wait_time, url, …)."""
        return dict(self.model_extra or {})


class Task(BaseModel):
    """A task (GET /task): its ``sub_tasks`` run in order, again and again with ``loop_flag``.

    ``state``: WAITTING (sic), WORKING, PAUSED, COMPLETE, CANCELLED or ERROR; ``progress``
    the percent of this pass's actions done; ``loop_count`` the passes completed.
    """

    model_config = ConfigDict(frozen=True, extra="allow")

    id: str
    name: str = ""
    state: str
    progress: float = 0
    loop_flag: bool = False
    loop_count: int = 0
    current_task: TaskAction | None = None
    sub_tasks: list[TaskAction] = Field(default_factory=list)

    @property
    def ended(self) -> bool:
        """The task is COMPLETE, CANCELLED or ERROR."""
        return self.state in TASK_ENDINGS

    @property
    def running(self) -> bool:
        """The task is WORKING or PAUSED: the robot may move for it."""
        return self.state in ("WORKING", "PAUSED")
