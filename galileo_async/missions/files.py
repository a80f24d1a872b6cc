"""Mission files: YAML in, YAML out, and the published JSON Schema (docs/missions.md).

Loading reports every problem of a file at once, each with the file, the line and the step
(``patrol.yaml:12: steps[2] (name 'dock'): on_failure: …``). PyYAML (the extra
``missions``) is imported inside the functions that need it, so ``import
galileo_async.missions`` works without it.
"""

from __future__ import annotations

import difflib
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from pydantic import ValidationError

from .model import ACTION_KEYS, LoopStep, Mission, OnFailure, step_action

if TYPE_CHECKING:
    from yaml import Node

__all__ = [
    "YAML_HINT",
    "FileProblem",
    "MissionFileError",
    "dump_mission",
    "dump_yaml",
    "load_mission",
    "mission_data",
    "mission_schema",
    "parse_mission",
    "yaml_mapping",
    "yaml_module",
]

#: How to get PyYAML, which mission files need.
YAML_HINT = "pip install 'galileo-async[missions]'"


@dataclass(frozen=True)
class FileProblem:
    """One problem of a mission file: where (line, step path, step name) and what."""

    source: str
    line: int | None
    step: str | None
    name: str | None
    message: str

    def __str__(self) -> str:
        where = self.source if self.line is None else f"{self.source}:{self.line}"
        if self.step is None:
            return f"{where}: {self.message}"
        named = "" if self.name is None else f" (name {self.name!r})"
        return f"{where}: {self.step}{named}: {self.message}"


class MissionFileError(ValueError):
    """A mission file that does not load; ``problems`` holds one line for each problem.

    ``source``, ``line`` and ``step`` locate the first problem; ``details`` are the
    problems as FileProblem.
    """

    def __init__(self, details: list[FileProblem]) -> None:
        self.details = details
        self.problems = [str(problem) for problem in details]
        first = details[0]
        self.source = first.source
        self.line = first.line
        self.step = first.step if first.name is None else (first.step or first.name)
        count = f"{len(details)} problems" if len(details) > 1 else "1 problem"
        super().__init__(f"{first.source}: {count}:\n" + "\n".join(self.problems))


def yaml_module() -> Any:
    """The ``yaml`` module; ModuleNotFoundError saying how to install it when it is missing."""
    try:
        import yaml
    except ModuleNotFoundError as exc:
        message = f"mission files need PyYAML (yaml is not installed): {YAML_HINT}"
        raise ModuleNotFoundError(message, name="yaml") from exc
    return yaml


def load_mission(path: str | Path) -> Mission:
    """The mission in the YAML file ``path``; MissionFileError naming every problem (OSError
    when the file cannot be read)."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        problem = FileProblem(str(path), None, None, None, f"not UTF-8: {exc}")
        raise MissionFileError([problem]) from None
    return parse_mission(text, source=str(path))


def parse_mission(text: str, *, source: str = "<string>") -> Mission:
    """The mission in YAML ``text``; MissionFileError naming every problem with its line."""
    message = "no mission here: a mission file is a mapping with `mission:` and `steps:`"
    data, lines = yaml_mapping(text, source=source, not_a_mapping=message)
    return mission_from_data(data, source=source, lines=lines)


def yaml_mapping(text: str, *, source: str, not_a_mapping: str) -> tuple[dict[str, Any], _Lines]:
    """The YAML document ``text`` (a mapping) and its lines; MissionFileError with the line
    of a YAML error, or ``not_a_mapping`` when the document is something else."""
    yaml = yaml_module()
    loader = yaml.SafeLoader(text)
    try:
        node = loader.get_single_node()
        data = None if node is None else loader.construct_document(node)
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        line = None if mark is None else mark.line + 1
        what = " ".join(str(part) for part in (exc.context, exc.problem) if part)
        raise MissionFileError([FileProblem(source, line, None, None, f"YAML: {what}")]) from None
    except yaml.YAMLError as exc:
        raise MissionFileError([FileProblem(source, None, None, None, f"YAML: {exc}")]) from None
    finally:
        loader.dispose()
    if not isinstance(data, dict):
        line = None if node is None else node.start_mark.line + 1
        raise MissionFileError([FileProblem(source, line, None, None, not_a_mapping)])
    return data, _Lines.of(node)


def mission_from_data(
    data: dict[str, Any], *, source: str = "<data>", lines: _Lines | None = None
) -> Mission:
    """A Mission from plain data (parsed YAML or JSON), problems as in parse_mission."""
    lines = lines or _Lines()
    problems = [FileProblem(source, line, None, None, message) for line, message in lines.twice]
    problems += _name_problems(data, source, lines)
    try:
        mission = Mission.model_validate(data)
    except ValidationError as exc:
        for error in exc.errors():
            if not error["loc"] and problems_cover(error["msg"]):
                continue  # the names pass above said it, with lines
            problems.append(_translate(error, data, source, lines))
    else:
        if not problems:
            return mission
    problems.sort(key=lambda problem: problem.line or 0)
    raise MissionFileError(problems)


def problems_cover(message: str) -> bool:
    """True for the mission-wide name errors that _name_problems reports with their lines."""
    return "step names must be unique" in message or "a step that does not exist" in message


class _Lines:
    """Line numbers of a YAML document by data path, and the keys given twice."""

    def __init__(self) -> None:
        self.at: dict[tuple[Any, ...], int] = {}
        self.twice: list[tuple[int, str]] = []

    @classmethod
    def of(cls, node: Node) -> _Lines:
        lines = cls()
        lines._visit(node, ())
        return lines

    def _visit(self, node: Node, path: tuple[Any, ...]) -> None:
        import yaml

        self.at.setdefault(path, node.start_mark.line + 1)
        if isinstance(node, yaml.MappingNode):
            seen: dict[Any, int] = {}
            for key_node, value_node in node.value:
                key = key_node.value
                line = key_node.start_mark.line + 1
                if key in seen:
                    first = f"first on line {seen[key]}"
                    self.twice.append((line, f"key {key!r} given twice ({first})"))
                    continue
                seen[key] = line
                here = (*path, key)
                self.at[here] = line
                self._visit(value_node, here)
        elif isinstance(node, yaml.SequenceNode):
            for index, item in enumerate(node.value):
                self._visit(item, (*path, index))

    def under(self, path: tuple[Any, ...]) -> _Lines:
        """The lines of the part of the document at ``path``, by paths from there."""
        part = _Lines()
        size = len(path)
        part.at = {key[size:]: line for key, line in self.at.items() if key[:size] == path}
        return part

    def line(self, path: tuple[Any, ...]) -> int | None:
        """The line of ``path``, else of its nearest ancestor the document has."""
        for end in range(len(path), -1, -1):
            line = self.at.get(path[:end])
            if line is not None:
                return line
        return None


@dataclass
class _Where:
    """A pydantic error location read against the data: the step it is in, and the field."""

    data_path: tuple[Any, ...] = ()
    step: str | None = None
    name: str | None = None
    field: str = ""


def _locate(loc: tuple[Any, ...], data: Any) -> _Where:
    where = _Where()
    text = ""
    field: list[str] = []
    node: Any = data
    items = list(loc)
    index = 0
    while index < len(items):
        part = items[index]
        index += 1
        where.data_path = (*where.data_path, part)
        node = node[part] if _has(node, part) else None
        if isinstance(part, int) and field and field[-1] == "steps":
            # A step: the steps' list index; pydantic's next element is the union's tag.
            text = ".".join([text, *field[:-1], f"steps[{part}]"]).lstrip(".")
            where.step, field = text, []
            where.name = node.get("name") if isinstance(node, dict) else None
            if not isinstance(where.name, str):
                where.name = None
            if index < len(items) and items[index] in ACTION_KEYS:
                index += 1
            continue
        field.append(str(part) if not isinstance(part, int) else f"[{part}]")
    where.field = ".".join(field).replace(".[", "[")
    return where


def _has(node: Any, part: Any) -> bool:
    if isinstance(node, dict):
        return part in node
    return isinstance(node, list) and isinstance(part, int) and 0 <= part < len(node)


def _translate(error: Any, data: Any, source: str, lines: _Lines) -> FileProblem:
    """A pydantic error as a FileProblem: the line, the step, the field, a plain message."""
    where = _locate(tuple(error["loc"]), data)
    kind = error["type"]
    message = str(error["msg"]).removeprefix("Value error, ")
    value = error.get("input")
    if kind == "extra_forbidden":
        key = where.data_path[-1] if where.data_path else "?"
        known = _known_keys(where)
        near = difflib.get_close_matches(str(key), known, n=1)
        hint = f" (did you mean {near[0]!r}?)" if near else ""
        return FileProblem(
            source, lines.line(where.data_path), where.step, where.name,
            f"unknown key {key!r}{hint}",
        )  # fmt: skip
    if kind == "step_action":
        message = _action_message(value)
    elif kind == "missing":
        message = "missing (required)"
    elif value is not None and not isinstance(value, dict | list) and kind != "value_error":
        message = f"{message} (got {value!r})"
    field = f"{where.field}: " if where.field else ""
    message = message.removeprefix(field)  # a validator that names its field already
    return FileProblem(source, lines.line(where.data_path), where.step, where.name, field + message)


def _known_keys(where: _Where) -> list[str]:
    common = ["name", "on_failure", "timeout"]
    if where.step is None:
        return list(Mission.model_fields)
    return [*ACTION_KEYS, *common]


def _action_message(value: Any) -> str:
    keys = ", ".join(ACTION_KEYS)
    if not isinstance(value, dict):
        return f"a step is a mapping with one action key ({keys}), not {value!r}"
    given = [key for key in value if key in ACTION_KEYS]
    if len(given) > 1:
        return f"one action per step: {', '.join(given)} are several (make them separate steps)"
    for key in value:
        near = difflib.get_close_matches(str(key), list(ACTION_KEYS), n=1)
        if near and key not in ("name", "on_failure", "timeout"):
            return f"no action key: unknown key {key!r} (did you mean {near[0]!r}?)"
    return f"no action key: a step needs exactly one of {keys}"


def _raw_steps(
    steps: Any, prefix: str = "steps", path: tuple[Any, ...] = ("steps",)
) -> Iterator[tuple[str, tuple[Any, ...], dict[str, Any]]]:
    """Every step mapping of raw data, depth first: (step path, data path, mapping)."""
    if not isinstance(steps, list):
        return
    for index, step in enumerate(steps):
        if not isinstance(step, dict):
            continue
        text, here = f"{prefix}[{index}]", (*path, index)
        yield text, here, step
        loop = step.get("loop")
        if isinstance(loop, dict):
            yield from _raw_steps(loop.get("steps"), f"{text}.loop.steps", (*here, "loop", "steps"))


def _name_problems(data: dict[str, Any], source: str, lines: _Lines) -> list[FileProblem]:
    """Step names given twice, and on_failure policies that go to no step, with lines."""
    problems: list[FileProblem] = []
    named: dict[str, str] = {}
    jumps: list[tuple[str, tuple[Any, ...], str | None, str]] = []
    for text, path, step in _raw_steps(data.get("steps")):
        name = step.get("name") if isinstance(step.get("name"), str) else None
        if name is not None:
            if name in named:
                problems.append(FileProblem(
                    source, lines.line((*path, "name")), text, name,
                    f"name: {name!r} is the name of {named[name]} too (names are unique)",
                ))  # fmt: skip
            else:
                named[name] = text
        target = _jump(step.get("on_failure"))
        if target is not None:
            jumps.append((text, path, name, target))
    for text, path, name, target in jumps:
        if target not in named:
            near = difflib.get_close_matches(target, list(named), n=1)
            hint = f" (did you mean {near[0]!r}?)" if near else ""
            problems.append(FileProblem(
                source, lines.line((*path, "on_failure")), text, name,
                f"on_failure: goes to {target!r}, a step that does not exist{hint}",
            ))  # fmt: skip
    return problems


def _jump(policy: Any) -> str | None:
    if isinstance(policy, str):
        words = policy.split()
        return words[1] if len(words) == 2 and words[0] == "goto" else None
    if isinstance(policy, dict) and isinstance(policy.get("goto"), str):
        return str(policy["goto"])
    return None


def dump_mission(mission: Mission) -> str:
    """``mission`` as mission-file YAML, shorthands where they say the same; parse_mission
    of it gives ``mission`` back."""
    return dump_yaml(mission_data(mission))


def mission_data(mission: Mission) -> dict[str, Any]:
    """``mission`` as the plain data of its file (shorthands where they say the same)."""
    data = mission.model_dump(mode="json", by_alias=True, exclude_defaults=True, exclude={"steps"})
    data["steps"] = [_step_data(step) for step in mission.steps]
    return data


def dump_yaml(data: Any) -> str:
    """``data`` as YAML in file order, small mappings of mission_data on one line."""
    yaml = yaml_module()
    return str(yaml.dump(data, Dumper=_dumper(yaml), sort_keys=False, allow_unicode=True))


class _Flow(dict[str, Any]):
    """A small mapping written on one line (``{x: 1.5, y: 2.0}``)."""


def _dumper(yaml: Any) -> Any:
    class Dumper(yaml.SafeDumper):  # type: ignore[misc]
        pass

    def flow(dumper: Any, value: _Flow) -> Any:
        return dumper.represent_mapping("tag:yaml.org,2002:map", value, flow_style=True)

    Dumper.add_representer(_Flow, flow)
    return Dumper


def _step_data(step: Any) -> dict[str, Any]:
    action = step_action(step)
    assert action is not None  # a built Step has exactly one
    if isinstance(step, LoopStep):
        loop: dict[str, Any] = {}
        if step.loop.count is not None:
            loop["count"] = step.loop.count
        loop["steps"] = [_step_data(inner) for inner in step.loop.steps]
        value: Any = loop
    else:
        dumped = step.model_dump(mode="json", by_alias=True, exclude_defaults=True)
        value = _compact(action, dumped.get(action))
    out: dict[str, Any] = {action: value}
    if step.name is not None:
        out["name"] = step.name
    if step.on_failure != OnFailure():
        out["on_failure"] = _policy_text(step.on_failure)
    if step.timeout is not None:
        out["timeout"] = step.timeout
    return out


def _compact(action: str, value: Any) -> Any:
    if action == "wait" and set(value) == {"release"}:
        return value["release"]
    if action == "switch_map" and set(value) == {"map"}:
        return value["map"]
    if isinstance(value, dict) and all(not isinstance(v, dict | list) for v in value.values()):
        return _Flow(value)
    return value


def _policy_text(policy: OnFailure) -> Any:
    if policy.retry == 0 and policy.then != "abort":
        return "skip" if policy.then == "skip" else f"goto {policy.goto}"
    if policy.then == "abort":
        return f"retry {policy.retry}"
    return _Flow(policy.model_dump(exclude_defaults=True))


#: The shorthands files may use where the model holds a mapping: (definition, property) →
#: the other forms the property takes.
_SHORTHANDS: dict[tuple[str, str], list[dict[str, Any]]] = {
    ("WaitStep", "wait"): [{"type": "string", "minLength": 1}],
    ("SwitchMapStep", "switch_map"): [{"type": "string", "minLength": 1}],
    ("ChargeStep", "charge"): [{"type": "null"}, {"const": True}],
    ("Loop", "count"): [{"const": "forever"}],
    ("CallOut", "expect_status"): [{"type": "integer"}],
}
_POLICY_TEXT = {"type": "string", "pattern": r"^(abort|skip|retry [0-9]+|goto \S+)$"}


def mission_schema() -> dict[str, Any]:
    """The JSON Schema (2020-12) of mission files, shorthands included (as published in
    docs/mission.schema.json)."""
    schema = Mission.model_json_schema(by_alias=True)
    definitions = schema["$defs"]
    for (definition, prop), forms in _SHORTHANDS.items():
        properties = definitions[definition]["properties"]
        properties[prop] = _any_of(properties[prop], forms)
    for definition in definitions.values():
        properties = definition.get("properties", {})
        if "on_failure" in properties:
            properties["on_failure"] = _any_of(properties["on_failure"], [_POLICY_TEXT])
    return {
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "title": "Galileo mission",
        **{key: value for key, value in schema.items() if key != "title"},
    }


def _any_of(schema: dict[str, Any], forms: list[dict[str, Any]]) -> dict[str, Any]:
    keep: dict[str, Any] = {
        key: schema[key] for key in ("default", "description", "title") if key in schema
    }
    body = {key: value for key, value in schema.items() if key not in keep}
    options = body["anyOf"] if set(body) == {"anyOf"} else [body]
    return {"anyOf": [*options, *forms], **keep}
