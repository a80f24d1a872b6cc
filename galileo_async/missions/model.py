"""The mission model: typed steps, loops and failure policies (docs/missions.md).

A mission file (YAML) is a list of steps; each step is a mapping with exactly one action
key (``goto: 3``, ``dwell: 30``, ``loop: {...}``) and the common keys ``name``,
``on_failure`` and ``timeout``. Everything is checked when the model is built, before
anything is sent to a robot; what needs the robot (its targets, its map) is checked by
``missions.check``.
"""

from __future__ import annotations

import math
from typing import Annotated, Any, Literal

from pydantic import (
    BaseModel,
    ConfigDict,
    Discriminator,
    Field,
    Tag,
    field_validator,
    model_validator,
)

__all__ = [
    "ACTION_KEYS",
    "CallOut",
    "CallStep",
    "ChargeStep",
    "ChargeUntil",
    "DwellStep",
    "GotoPointStep",
    "GotoPoseStep",
    "GotoStep",
    "LinkLossPolicy",
    "LocalMove",
    "LocalMoveStep",
    "Loop",
    "LoopStep",
    "MapSwitch",
    "Mission",
    "OnFailure",
    "Point",
    "PoseGoal",
    "Release",
    "SayStep",
    "Step",
    "SwitchMapStep",
    "WaitStep",
    "step_action",
    "step_paths",
    "walk",
]


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class OnFailure(_Strict):
    """What a failed step does: ``retry`` times more, then ``then``: abort, skip or goto."""

    retry: int = Field(0, ge=0, le=100, description="further attempts before `then`")
    then: Literal["abort", "skip", "goto"] = "abort"
    goto: str | None = Field(None, description="the step name to continue at (then: goto)")

    @model_validator(mode="after")
    def _goto_named(self) -> OnFailure:
        if (self.then == "goto") != (self.goto is not None):
            raise ValueError("`goto: NAME` goes with `then: goto`, and only with it")
        return self


def _policy(value: Any) -> Any:
    """Shorthands: "abort", "skip", "retry 2", {"goto": "dock"} → OnFailure's fields."""
    if isinstance(value, str):
        words = value.split()
        if words in (["abort"], ["skip"]):
            return {"then": words[0]}
        if len(words) == 2 and words[0] == "retry" and words[1].isdigit():
            return {"retry": int(words[1])}
        if len(words) == 2 and words[0] == "goto":
            return {"then": "goto", "goto": words[1]}
        raise ValueError(f"on_failure: {value!r} is none of abort, skip, retry N, goto STEP")
    if isinstance(value, dict) and "goto" in value and "then" not in value:
        return {**value, "then": "goto"}
    return value


class _StepBase(_Strict):
    name: str | None = Field(None, min_length=1, description="unique within the mission")
    on_failure: OnFailure = Field(default_factory=OnFailure)
    timeout: float | None = Field(None, gt=0, description="seconds for the whole step")

    @field_validator("on_failure", mode="before")
    @classmethod
    def _shorthand(cls, value: Any) -> Any:
        return _policy(value)


class Point(_Strict):
    """A point in the map frame, metres."""

    x: float = Field(allow_inf_nan=False)
    y: float = Field(allow_inf_nan=False)


class PoseGoal(Point):
    """A pose in the map frame: metres and radians."""

    theta: float = Field(0.0, allow_inf_nan=False)


class GotoStep(_StepBase):
    """Drive to a target id of the robot's map (robot.goto)."""

    goto: int = Field(ge=0, le=255)


class GotoPointStep(_StepBase):
    """Drive to a point (robot.goto_point: dynamic targets)."""

    goto_point: Point


class GotoPoseStep(_StepBase):
    """Drive to a pose (robot.http.goto_pose: http:// only)."""

    goto_pose: PoseGoal


class DwellStep(_StepBase):
    """Stand still for seconds."""

    dwell: float = Field(ge=0, allow_inf_nan=False)


class SayStep(_StepBase):
    """Speak a text (robot.http.say: http:// only)."""

    say: str = Field(min_length=1)


class Release(_Strict):
    """Wait until the release named ``release`` is given (by the runner's caller)."""

    release: str = Field(min_length=1, description="the name the caller binds a trigger to")
    timeout: float | None = Field(None, gt=0)


class WaitStep(_StepBase):
    """Wait for a release: an awaitable in Python; a key, a file, HTTP or MQTT from the CLI."""

    wait: Release

    @field_validator("wait", mode="before")
    @classmethod
    def _name_only(cls, value: Any) -> Any:
        return {"release": value} if isinstance(value, str) else value


class CallOut(_Strict):
    """An HTTP request to an outside system (a door, a lift) and the answer expected."""

    url: str = Field(pattern=r"^https?://")
    method: Literal["GET", "POST", "PUT", "DELETE", "PATCH"] = "POST"
    json_body: Any = Field(None, alias="json")
    headers: dict[str, str] = Field(default_factory=dict)
    timeout: float = Field(10.0, gt=0)
    expect_status: list[int] = Field(default_factory=lambda: [200])
    expect_json: dict[str, Any] | None = Field(
        None, description="keys the JSON answer must hold with these values"
    )

    model_config = ConfigDict(extra="forbid", frozen=True, populate_by_name=True)

    @field_validator("expect_status", mode="before")
    @classmethod
    def _one_status(cls, value: Any) -> Any:
        return [value] if isinstance(value, int) else value


class CallStep(_StepBase):
    """Call out over HTTP."""

    call: CallOut


class MapSwitch(_Strict):
    """Switch the robot's map (and path) and restart navigation on it."""

    map: str = Field(min_length=1)
    path: str | None = Field(None, min_length=1)


class SwitchMapStep(_StepBase):
    """Switch map (http:// only)."""

    switch_map: MapSwitch

    @field_validator("switch_map", mode="before")
    @classmethod
    def _name_only(cls, value: Any) -> Any:
        return {"map": value} if isinstance(value, str) else value


class ChargeUntil(_Strict):
    """Go to the dock and charge; stay until the battery shows a level (% or V), if given."""

    until_percent: float | None = Field(None, gt=0, le=100)
    until_volts: float | None = Field(None, gt=0, allow_inf_nan=False)

    @model_validator(mode="after")
    def _one_level(self) -> ChargeUntil:
        if self.until_percent is not None and self.until_volts is not None:
            raise ValueError("give until_percent or until_volts, not both")
        return self


class ChargeStep(_StepBase):
    """Dock and charge (robot.start_charging)."""

    charge: ChargeUntil

    @field_validator("charge", mode="before")
    @classmethod
    def _bare(cls, value: Any) -> Any:
        return {} if value is None or value is True else value


class LocalMove(_Strict):
    """Turn by ``angle`` radians, then drive ``distance`` metres (negative: backwards)."""

    distance: float = Field(0.0, allow_inf_nan=False, ge=-10, le=10)
    angle: float = Field(0.0, allow_inf_nan=False, ge=-2 * math.pi, le=2 * math.pi)


class LocalMoveStep(_StepBase):
    """A local move."""

    local_move: LocalMove


class Loop(_Strict):
    """Run ``steps`` ``count`` times (None: until stopped)."""

    count: int | None = Field(None, ge=1)
    steps: list[Step] = Field(min_length=1)

    @field_validator("count", mode="before")
    @classmethod
    def _forever(cls, value: Any) -> Any:
        return None if value == "forever" else value


class LoopStep(_StepBase):
    """A loop over steps."""

    loop: Loop


#: The action key of each step kind, in the order they are documented.
ACTION_KEYS: dict[str, type[_StepBase]] = {
    "goto": GotoStep,
    "goto_point": GotoPointStep,
    "goto_pose": GotoPoseStep,
    "dwell": DwellStep,
    "say": SayStep,
    "wait": WaitStep,
    "call": CallStep,
    "switch_map": SwitchMapStep,
    "charge": ChargeStep,
    "local_move": LocalMoveStep,
    "loop": LoopStep,
}


def step_action(value: Any) -> str | None:
    """The one action key of a step (a mapping or a model), or None when not exactly one."""
    if isinstance(value, dict):
        keys = value.keys()
    elif isinstance(value, BaseModel):
        keys = type(value).model_fields.keys()
    else:  # a list, a number, a string where a step belongs
        return None
    found = [key for key in keys if key in ACTION_KEYS]
    return found[0] if len(found) == 1 else None


Step = Annotated[
    Annotated[GotoStep, Tag("goto")]
    | Annotated[GotoPointStep, Tag("goto_point")]
    | Annotated[GotoPoseStep, Tag("goto_pose")]
    | Annotated[DwellStep, Tag("dwell")]
    | Annotated[SayStep, Tag("say")]
    | Annotated[WaitStep, Tag("wait")]
    | Annotated[CallStep, Tag("call")]
    | Annotated[SwitchMapStep, Tag("switch_map")]
    | Annotated[ChargeStep, Tag("charge")]
    | Annotated[LocalMoveStep, Tag("local_move")]
    | Annotated[LoopStep, Tag("loop")],
    Discriminator(
        step_action,
        custom_error_type="step_action",
        custom_error_message=f"a step needs exactly one of: {', '.join(ACTION_KEYS)}",
    ),
]


class LinkLossPolicy(_Strict):
    """What the mission does when the robot's link is lost mid-step."""

    then: Literal["abort", "wait"] = "abort"
    wait: float = Field(30.0, gt=0, description="seconds to wait for the link (then: wait)")


class Mission(_Strict):
    """A named plan of steps; names of steps are unique, goto policies name existing steps."""

    mission: str = Field(min_length=1, description="the mission's name")
    version: Literal[1] = 1
    description: str | None = None
    on_link_loss: LinkLossPolicy = Field(default_factory=LinkLossPolicy)
    steps: list[Step] = Field(min_length=1)

    @model_validator(mode="after")
    def _names(self) -> Mission:
        names: list[str] = []
        targets: list[str] = []
        for step in walk(self.steps):
            if step.name is not None:
                names.append(step.name)
            if step.on_failure.goto is not None:
                targets.append(step.on_failure.goto)
        twice = sorted({name for name in names if names.count(name) > 1})
        if twice:
            raise ValueError(f"step names must be unique: {', '.join(twice)}")
        missing = sorted(set(targets) - set(names))
        if missing:
            raise ValueError(f"on_failure goes to a step that does not exist: {', '.join(missing)}")
        return self


def walk(steps: list[Any]) -> list[_StepBase]:
    """Every step, loops' steps included, depth first in file order."""
    found: list[_StepBase] = []
    for step in steps:
        found.append(step)
        if isinstance(step, LoopStep):
            found.extend(walk(step.loop.steps))
    return found


def step_paths(steps: list[Any], prefix: str = "steps") -> list[tuple[str, _StepBase]]:
    """Every step with its path ("steps[2].loop.steps[0]"), in walk()'s order."""
    found: list[tuple[str, _StepBase]] = []
    for index, step in enumerate(steps):
        path = f"{prefix}[{index}]"
        found.append((path, step))
        if isinstance(step, LoopStep):
            found.extend(step_paths(step.loop.steps, f"{path}.loop.steps"))
    return found


Loop.model_rebuild()
LoopStep.model_rebuild()
Mission.model_rebuild()
