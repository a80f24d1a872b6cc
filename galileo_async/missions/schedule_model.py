"""The schedule model: windows in a time zone, date exclusions, battery thresholds.

A schedule file (YAML) names a mission per time window (docs/missions-schedule.md).
Everything that needs no robot is checked here: the model when it is built,
``check_schedule`` for what is allowed but probably unmeant (overlapping windows).
``occurrences`` turns the windows into instants: the one place wall times in the
schedule's zone become aware datetimes, daylight saving time included.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from dataclasses import dataclass
from datetime import date, datetime, time, timedelta, timezone, tzinfo
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal
from zoneinfo import ZoneInfo, ZoneInfoNotFoundError

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from ..battery import battery_charge
from .check import Problem, WindowCheck
from .files import (
    FileProblem,
    MissionFileError,
    dump_yaml,
    load_mission,
    mission_data,
    mission_from_data,
    yaml_mapping,
)
from .model import Mission

if TYPE_CHECKING:
    from .importers import ImportedPlan, ImportedWindow

__all__ = [
    "DAY_NAMES",
    "BatteryPolicy",
    "DateRange",
    "Occurrence",
    "Schedule",
    "Window",
    "check_schedule",
    "dump_schedule",
    "imported_windows",
    "is_schedule",
    "load_schedule",
    "occurrences",
    "parse_schedule",
    "schedule_from_plan",
    "schedule_plan",
    "zone_of",
]

#: Day names in the file, Monday first (datetime.weekday()'s numbers).
DAY_NAMES = ("mon", "tue", "wed", "thu", "fri", "sat", "sun")
_DAY_SETS = {
    "every day": tuple(range(7)),
    "weekdays": (0, 1, 2, 3, 4),
    "weekends": (5, 6),
}


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


def _clock_time(value: Any) -> Any:
    """ "HH:MM" → time; YAML 1.1 reads an unquoted 08:00 as 480 (sexagesimal minutes)."""
    if isinstance(value, int) and not isinstance(value, bool) and 0 <= value < 24 * 60:
        return time(value // 60, value % 60)
    if isinstance(value, str):
        hours, colon, minutes = value.strip().partition(":")
        digits = colon and hours.isdigit() and minutes.isdigit() and len(minutes) == 2
        if digits and int(hours) < 24 and int(minutes) < 60:
            return time(int(hours), int(minutes))
        raise ValueError(f"{value!r} is not a time of day HH:MM")
    return value


class Window(_Strict):
    """A time window on some days: its mission runs from ``start`` until ``stop``."""

    name: str | None = Field(None, min_length=1)
    days: tuple[int, ...] = Field(
        description='"every day", "weekdays", "weekends", or a list of mon..sun'
    )
    start: time
    stop: time = Field(description="before start: the window runs over midnight")
    mission: str | Mission = Field(description="a mission file (relative to the schedule) or one")
    stop_pose: int | Literal["dock"] | None = Field(
        None, description="where to go when the window closes: a target id or the dock"
    )
    on_overlap: Literal["wait", "preempt", "skip"] = Field(
        "wait", description="this window opens while another runs: wait, preempt it, or skip"
    )

    @field_validator("days", mode="before")
    @classmethod
    def _days(cls, value: Any) -> Any:
        if isinstance(value, str):
            value = _DAY_SETS.get(value.strip().lower(), [value])
        if not isinstance(value, (list, tuple)) or not value:
            raise ValueError('days: "every day", "weekdays", "weekends" or a list of mon..sun')
        found: list[int] = []
        for day in value:
            if isinstance(day, int) and 0 <= day < 7:
                found.append(day)
            elif isinstance(day, str) and day.strip().lower()[:3] in DAY_NAMES:
                found.append(DAY_NAMES.index(day.strip().lower()[:3]))
            else:
                raise ValueError(f"{day!r} is not a day (mon..sun)")
        return tuple(sorted(set(found)))

    @field_validator("start", "stop", mode="before")
    @classmethod
    def _times(cls, value: Any) -> Any:
        return _clock_time(value)

    @field_validator("stop_pose", mode="before")
    @classmethod
    def _pose(cls, value: Any) -> Any:
        if isinstance(value, int) and not isinstance(value, bool) and not 0 <= value <= 255:
            raise ValueError(f"stop_pose: target id {value} is not 0..255")
        return value

    @model_validator(mode="after")
    def _not_empty(self) -> Window:
        if self.start == self.stop:
            raise ValueError("start and stop are equal: the window would be empty")
        return self

    @property
    def over_midnight(self) -> bool:
        """True when the window ends on the day after it starts."""
        return self.stop < self.start


class DateRange(_Strict):
    """Dates excluded, ``first`` to ``last`` inclusive (one date: both the same)."""

    first: date
    last: date

    @model_validator(mode="before")
    @classmethod
    def _shorthand(cls, value: Any) -> Any:
        if isinstance(value, (date, str)):
            text = str(value)
            first, dots, last = text.partition("..")
            return {"first": first.strip(), "last": (last if dots else first).strip()}
        if isinstance(value, dict) and set(value) == {"from", "to"}:
            return {"first": value["from"], "last": value["to"]}
        return value

    @model_validator(mode="after")
    def _ordered(self) -> DateRange:
        if self.last < self.first:
            raise ValueError(f"the range ends ({self.last}) before it begins ({self.first})")
        return self

    def __contains__(self, day: object) -> bool:
        return isinstance(day, date) and self.first <= day <= self.last


class BatteryPolicy(_Strict):
    """Go charge below a level, resume the mission at a level (percent from
    galileo_async.battery's curve, or V)."""

    go_charge_below_percent: float | None = Field(None, gt=0, lt=100)
    go_charge_below_volts: float | None = Field(None, gt=0, allow_inf_nan=False)
    resume_at_percent: float | None = Field(None, gt=0, le=100)
    resume_at_volts: float | None = Field(None, gt=0, allow_inf_nan=False)
    dock_target: int | None = Field(
        None, ge=0, le=255, description="a target near the dock, driven to before docking"
    )

    @model_validator(mode="after")
    def _levels(self) -> BatteryPolicy:
        below = (self.go_charge_below_percent, self.go_charge_below_volts)
        resume = (self.resume_at_percent, self.resume_at_volts)
        if sum(level is not None for level in below) != 1:
            raise ValueError("give one of go_charge_below_percent, go_charge_below_volts")
        if sum(level is not None for level in resume) > 1:
            raise ValueError("give resume_at_percent or resume_at_volts, not both")
        if self.percent(self.go_charge_below_percent, self.go_charge_below_volts) >= self.percent(
            self.resume_at_percent, self.resume_at_volts, 100.0
        ):
            raise ValueError("the resume level must be above the go-charge level")
        return self

    @staticmethod
    def percent(percent: float | None, volts: float | None, default: float = 0.0) -> float:
        """A level in percent, whichever way it was given."""
        if percent is not None:
            return percent
        return battery_charge(volts) if volts is not None else default

    def low(self, volts: float) -> bool:
        """True when ``volts`` is below the go-charge level."""
        if self.go_charge_below_volts is not None:
            return volts < self.go_charge_below_volts
        return battery_charge(volts) < (self.go_charge_below_percent or 0.0)

    def charged(self, volts: float) -> bool:
        """True when ``volts`` reached the resume level (never, when none is given)."""
        if self.resume_at_volts is not None:
            return volts >= self.resume_at_volts
        if self.resume_at_percent is not None:
            return battery_charge(volts) >= self.resume_at_percent
        return False


class Schedule(_Strict):
    """Windows in a time zone, each with its mission; dates excluded; battery thresholds."""

    schedule: str = Field("schedule", min_length=1, description="the schedule's name")
    version: Literal[1] = 1
    time_zone: str | None = Field(None, description="an IANA name; none: the host's zone")
    windows: list[Window] = Field(min_length=1)
    exclude: list[DateRange] = Field(default_factory=list)
    battery: BatteryPolicy | None = None
    on_window_close: Literal["finish_step", "stop_now"] = "finish_step"
    finish_step_timeout: float = Field(
        300.0, gt=0, allow_inf_nan=False, description="finish_step: longest wait for the step"
    )
    dock_target: int | None = Field(
        None, ge=0, le=255, description="a target near the dock, driven to before docking"
    )

    @field_validator("time_zone")
    @classmethod
    def _zone(cls, value: str | None) -> str | None:
        if value is not None:
            try:
                ZoneInfo(value)
            except (ZoneInfoNotFoundError, ValueError):
                raise ValueError(f"{value!r} is not a known IANA time zone") from None
        return value

    @field_validator("exclude", mode="before")
    @classmethod
    def _one_exclusion(cls, value: Any) -> Any:
        return [value] if isinstance(value, (str, date, dict)) else value

    def excluded(self, day: date) -> bool:
        """True when ``day`` is in an exclusion."""
        return any(day in span for span in self.exclude)


def zone_of(schedule: Schedule) -> tzinfo:
    """The schedule's time zone: its IANA name, or the host's local zone."""
    if schedule.time_zone is not None:
        return ZoneInfo(schedule.time_zone)
    local = datetime.now().astimezone().tzinfo
    return local if local is not None else timezone.utc


# --------------------------------------------------------------------------- instants
@dataclass(frozen=True)
class Occurrence:
    """One window on one day: its index, the day it starts on, its instants (UTC)."""

    index: int
    day: date
    start: datetime
    stop: datetime
    excluded: bool

    @property
    def key(self) -> tuple[datetime, int]:
        """The order occurrences open in: start, then the window's place in the file."""
        return (self.start, self.index)


def local_instant(day: date, wall: time, zone: tzinfo) -> datetime:
    """``wall`` on ``day`` in ``zone`` as an aware UTC datetime.

    A wall time the clocks skip (spring forward) is the gap's end; one they show twice
    (fall back) is its first occurrence.
    """
    naive = datetime.combine(day, wall)
    first = naive.replace(tzinfo=zone, fold=0).astimezone(timezone.utc)
    if first.astimezone(zone).replace(tzinfo=None) == naive:
        return first
    # In a gap: the transition lies between the two readings; find it to the second.
    low = naive.replace(tzinfo=zone, fold=1).astimezone(timezone.utc)
    high = first
    if low > high:
        low, high = high, low
    before = low.astimezone(zone).utcoffset()
    while high - low > timedelta(seconds=1):
        middle = low + (high - low) / 2
        if middle.astimezone(zone).utcoffset() == before:
            low = middle
        else:
            high = middle
    return high.replace(microsecond=0) if high.microsecond else high


def occurrences(schedule: Schedule, zone: tzinfo, since: date) -> Iterator[Occurrence]:
    """Every window's occurrences from the day ``since`` on, in the order they open."""
    day = since
    while True:
        found = []
        for index, window in enumerate(schedule.windows):
            if day.weekday() not in window.days:
                continue
            end_day = day + timedelta(days=1) if window.over_midnight else day
            start = local_instant(day, window.start, zone)
            stop = local_instant(end_day, window.stop, zone)
            if stop <= start:  # a window inside one DST gap
                continue
            found.append(Occurrence(index, day, start, stop, schedule.excluded(day)))
        yield from sorted(found, key=lambda occurrence: occurrence.key)
        day += timedelta(days=1)


# --------------------------------------------------------------------------- checks
def _minutes(window: Window) -> list[tuple[int, int]]:
    """The window's spans in minutes of the week (Monday 00:00 is 0)."""
    start = window.start.hour * 60 + window.start.minute
    stop = window.stop.hour * 60 + window.stop.minute
    length = (stop - start) % (24 * 60)
    week = 7 * 24 * 60
    spans = []
    for day in window.days:
        begin = day * 24 * 60 + start
        spans.append((begin, begin + length))
        if begin + length > week:
            spans.append((begin - week, begin + length - week))
    return spans


def check_schedule(schedule: Schedule) -> list[Problem]:
    """What the model allows but is probably unmeant: windows overlapping on a day (warnings).

    An overlap is no problem when the later window's ``on_overlap`` is given in the file:
    its policy says what happens then. A problem's ``step`` is the window (``windows[1]``).
    """
    problems = []
    for later, window in enumerate(schedule.windows):
        if "on_overlap" in window.model_fields_set:
            continue
        for earlier in range(later):
            other = schedule.windows[earlier]
            if any(
                a < d and c < b for a, b in _minutes(window) for c, d in _minutes(other)
            ):  # fmt: skip
                problems.append(
                    Problem(
                        f"windows[{later}]",
                        window.name,
                        f"overlaps windows[{earlier}] on a day: say what happens with"
                        " on_overlap: wait, preempt or skip",
                        "warning",
                    )
                )
    return problems


# --------------------------------------------------------------------------- files
def _where(path: tuple[Any, ...]) -> str:
    text = ""
    for key in path:
        text += f"[{key}]" if isinstance(key, int) else f".{key}" if text else str(key)
    return text


def parse_schedule(text: str, *, source: str = "<string>", base: Path | None = None) -> Schedule:
    """The Schedule in YAML ``text``; a window's mission file is read relative to ``base``.

    MissionFileError naming every problem with ``source``, its line and its window
    (``windows[1]``); a window's mission is loaded as ``load_mission`` loads one.
    """
    message = "no schedule here: a schedule file is a mapping with `windows:`"
    data, lines = yaml_mapping(text, source=source, not_a_mapping=message)
    problems = [FileProblem(source, line, None, None, message) for line, message in lines.twice]
    unloaded: set[int] = set()
    windows = data.get("windows")
    for index, window in enumerate(windows if isinstance(windows, list) else []):
        if not isinstance(window, dict):
            continue
        found = _load_window_mission(window, index, source, base, lines)
        if found:
            problems += found
            unloaded.add(index)
    try:
        schedule = Schedule.model_validate(data)
    except ValidationError as exc:
        for error in exc.errors():
            loc = tuple(error["loc"])
            if (
                loc[:1] == ("windows",)
                and loc[1:2]
                and loc[1] in unloaded
                and loc[2:3] == ("mission",)
            ):
                continue  # said above, with the mission's own lines
            problems.append(_problem(source, lines, data, loc, str(error["msg"])))
    if problems:
        problems.sort(key=lambda problem: problem.line or 0)
        raise MissionFileError(problems)
    return schedule


def _window_name(window: dict[str, Any]) -> str | None:
    name = window.get("name")
    return name if isinstance(name, str) else None


def _load_window_mission(
    window: dict[str, Any], index: int, source: str, base: Path | None, lines: Any
) -> list[FileProblem]:
    """Load the window's mission (a file, or inline) in place; its problems, if any."""
    where, name = f"windows[{index}]", _window_name(window)
    path = ("windows", index, "mission")
    mission = window.get("mission")
    try:
        if isinstance(mission, str):
            window["mission"] = load_mission((base or Path.cwd()) / mission)
        elif isinstance(mission, dict):
            window["mission"] = mission_from_data(mission, source=source, lines=lines.under(path))
    except OSError as exc:
        reason = exc.strerror or str(exc)
        return [FileProblem(source, lines.line(path), where, name, f"mission {mission}: {reason}")]
    except MissionFileError as exc:
        if isinstance(mission, str):
            return [
                FileProblem(source, lines.line(path), where, name, f"mission {mission}: {detail}")
                for detail in exc.details
            ]
        # Inline: the lines are the schedule's already (lines.under keeps them).
        inline = f"{where}.mission"
        return [
            FileProblem(
                source, detail.line, f"{inline}.{detail.step}" if detail.step else inline,
                detail.name, detail.message,
            )
            for detail in exc.details
        ]  # fmt: skip
    return []


def _problem(
    source: str, lines: Any, data: dict[str, Any], loc: tuple[Any, ...], message: str
) -> FileProblem:
    """A pydantic error of the schedule as a FileProblem: its line, its window, the field."""
    message = message.removeprefix("Value error, ")
    line = lines.line(loc)
    if loc[:1] == ("windows",) and len(loc) > 1 and isinstance(loc[1], int):
        windows = data.get("windows")
        window = windows[loc[1]] if isinstance(windows, list) and loc[1] < len(windows) else None
        name = _window_name(window) if isinstance(window, dict) else None
        field = _where(loc[2:])
        return FileProblem(source, line, f"windows[{loc[1]}]", name,
                           f"{field}: {message}" if field else message)  # fmt: skip
    field = _where(loc)
    return FileProblem(source, line, None, None, f"{field}: {message}" if field else message)


def load_schedule(path: str | Path) -> Schedule:
    """The schedule in the YAML file ``path``; its missions' paths are relative to it
    (MissionFileError naming every problem; OSError when it cannot be read)."""
    path = Path(path)
    return parse_schedule(path.read_text(encoding="utf-8"), source=str(path), base=path.parent)


# --------------------------------------------------------------------------- other forms
_SCHEDULE_KEY = re.compile(r"^windows\s*:", flags=re.MULTILINE)


def is_schedule(text: str) -> bool:
    """True for a schedule file's text: a top-level ``windows:`` (a mission has none)."""
    return _SCHEDULE_KEY.search(text) is not None


def imported_windows(schedule: Schedule) -> list[ImportedWindow]:
    """The schedule's windows in an import's terms (ISO weekdays, "HH:MM", stop pose -1
    for the dock), for check_plan."""
    from .importers import ImportedWindow

    found = []
    for window in schedule.windows:
        assert isinstance(window.mission, Mission)  # parse_schedule loads them
        pose = -1 if window.stop_pose == "dock" else window.stop_pose
        days = tuple(day + 1 for day in window.days)
        start, stop = window.start.strftime("%H:%M"), window.stop.strftime("%H:%M")
        found.append(ImportedWindow(days, start, stop, window.mission, stop_pose=pose))
    return found


def schedule_plan(schedule: Schedule) -> tuple[ImportedPlan, list[WindowCheck]]:
    """The schedule as check_plan takes it: its missions and windows, and check_schedule."""
    from .importers import ImportedPlan

    windows = imported_windows(schedule)
    plan = ImportedPlan(missions=[window.mission for window in windows], windows=windows)
    return plan, [lambda _windows: check_schedule(schedule)]


def schedule_from_plan(
    plan: ImportedPlan, *, name: str = "schedule", time_zone: str | None = None
) -> Schedule:
    """An imported plan's windows as a Schedule, each with its mission inline."""
    windows = []
    for window in plan.windows:
        pose = "dock" if window.stop_pose == -1 else window.stop_pose
        windows.append({
            "days": [day - 1 for day in window.days], "start": window.start,
            "stop": window.stop, "mission": window.mission, "stop_pose": pose,
        })  # fmt: skip
    return Schedule.model_validate({"schedule": name, "time_zone": time_zone, "windows": windows})


def dump_schedule(schedule: Schedule) -> str:
    """``schedule`` as schedule-file YAML, its missions inline; parse_schedule of it gives
    ``schedule`` back."""
    data = schedule.model_dump(mode="json", exclude_defaults=True, exclude={"windows"})
    data["windows"] = [_window_data(window) for window in schedule.windows]
    return dump_yaml(data)


def _window_data(window: Window) -> dict[str, Any]:
    data: dict[str, Any] = {}
    if window.name is not None:
        data["name"] = window.name
    data["days"] = [DAY_NAMES[day] for day in window.days]
    data["start"] = window.start.strftime("%H:%M")
    data["stop"] = window.stop.strftime("%H:%M")
    mission = window.mission
    data["mission"] = mission_data(mission) if isinstance(mission, Mission) else mission
    rest = window.model_dump(mode="json", exclude_defaults=True)
    data.update({key: rest[key] for key in ("stop_pose", "on_overlap") if key in rest})
    return data
