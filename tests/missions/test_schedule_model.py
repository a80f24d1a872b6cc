"""The schedule file: parsing with lines, checks, windows' instants (DST, midnight)."""

from __future__ import annotations

from datetime import date, datetime, time, timezone
from pathlib import Path
from zoneinfo import ZoneInfo

import pytest

from galileo_async.battery import battery_charge
from galileo_async.missions import Mission, MissionFileError, Problem
from galileo_async.missions.schedule_model import (
    BatteryPolicy,
    check_schedule,
    load_schedule,
    local_instant,
    occurrences,
    parse_schedule,
)

BERLIN = ZoneInfo("Europe/Berlin")

SCHEDULE = """\
schedule: office
time_zone: Europe/Berlin
windows:
  - days: weekdays
    start: "08:00"
    stop: "12:00"
    mission: patrol.yaml
    stop_pose: 0
  - days: [sat]
    start: 22:00
    stop: 02:00
    mission: {mission: night, steps: [{dwell: 60}]}
    stop_pose: dock
exclude: ["2026-12-25", "2026-12-31..2027-01-01", {from: 2026-08-01, to: 2026-08-15}]
battery: {go_charge_below_percent: 20, resume_at_volts: 27.0}
"""


def test_a_schedule_file_loads_with_its_mission_files(tmp_path: Path) -> None:
    (tmp_path / "patrol.yaml").write_text("mission: patrol\nsteps: [{goto: 1}, {goto: 2}]\n")
    (tmp_path / "office.yaml").write_text(SCHEDULE)
    plan = load_schedule(tmp_path / "office.yaml")
    first, night = plan.windows
    assert isinstance(first.mission, Mission)
    assert first.mission.mission == "patrol"
    assert first.days == (0, 1, 2, 3, 4)
    assert (night.start, night.stop, night.over_midnight) == (time(22), time(2), True)
    assert night.stop_pose == "dock"
    assert plan.excluded(date(2026, 12, 25))
    assert plan.excluded(date(2027, 1, 1))
    assert plan.excluded(date(2026, 8, 10))
    assert not plan.excluded(date(2026, 12, 26))
    assert plan.battery is not None
    assert plan.battery.low(23.9)
    assert not plan.battery.low(24.0)
    assert check_schedule(plan) == []


@pytest.mark.parametrize(
    ("text", "line", "window", "words"),
    [
        (SCHEDULE.replace('stop: "12:00"', 'stop: "12:75"'), 6, "windows[0]", "time of day"),
        (SCHEDULE.replace("days: [sat]", "days: [caturday]"), 9, "windows[1]", "not a day"),
        (SCHEDULE.replace("Europe/Berlin", "Mars/Olympus"), 2, None, "time zone"),
        (SCHEDULE.replace("stop_pose: dock", "stop_pose: 300"), 13, "windows[1]", "0..255"),
        (SCHEDULE.replace("resume_at_volts: 27.0", "resume_at_percent: 10"), 15, None, "above"),
        (SCHEDULE.replace("windows:", "windows: [\n"), 5, None, "flow"),
    ],
)
def test_errors_name_the_line_and_the_window(
    tmp_path: Path, text: str, line: int, window: str | None, words: str
) -> None:
    (tmp_path / "patrol.yaml").write_text("mission: patrol\nsteps: [{goto: 1}]\n")
    with pytest.raises(MissionFileError, match=words) as caught:
        parse_schedule(text, source="office.yaml", base=tmp_path)
    assert caught.value.line == line
    assert caught.value.step == window
    assert caught.value.problems[0].startswith(f"office.yaml:{line}: ")


def test_a_missing_mission_file_names_its_line(tmp_path: Path) -> None:
    with pytest.raises(MissionFileError, match=r"patrol\.yaml") as caught:
        parse_schedule(SCHEDULE, source="office.yaml", base=tmp_path)
    assert (caught.value.line, caught.value.step) == (7, "windows[0]")


def test_every_problem_has_its_line_and_an_inline_mission_its_step(tmp_path: Path) -> None:
    text = (
        SCHEDULE.replace('stop: "12:00"', 'stop: "12:75"')
        .replace("{dwell: 60}", "{dwel: 60}")
        .replace("stop_pose: dock", "stop_pose: 300")
    )
    (tmp_path / "patrol.yaml").write_text("mission: patrol\nsteps: [{goto: 1}]\n")
    with pytest.raises(MissionFileError) as caught:
        parse_schedule(text, source="office.yaml", base=tmp_path)
    assert [(d.line, d.step) for d in caught.value.details] == [
        (6, "windows[0]"), (12, "windows[1].mission.steps[0]"), (13, "windows[1]"),
    ]  # fmt: skip
    assert "did you mean 'dwell'" in caught.value.problems[1]


def test_a_broken_mission_file_names_both_files(tmp_path: Path) -> None:
    (tmp_path / "patrol.yaml").write_text("mission: patrol\nsteps:\n  - {goto: 1}\n  - {got: 2}\n")
    with pytest.raises(MissionFileError) as caught:
        load_schedule_text(tmp_path, SCHEDULE)
    [problem] = caught.value.problems
    assert problem.startswith("office.yaml:7: windows[0]: mission patrol.yaml: ")
    assert f"{tmp_path / 'patrol.yaml'}:4: steps[1]" in problem


def load_schedule_text(folder: Path, text: str) -> object:
    (folder / "office.yaml").write_text(text)
    return parse_schedule(text, source="office.yaml", base=folder)


def test_overlapping_windows_are_a_problem_unless_a_policy_is_given() -> None:
    mission = {"mission": "m", "steps": [{"dwell": 1}]}
    windows = [
        {"days": "every day", "start": "08:00", "stop": "12:00", "mission": mission},
        {"days": ["sun"], "start": "11:00", "stop": "13:00", "mission": mission},
        {"days": ["mon"], "start": "23:00", "stop": "01:00", "mission": mission},
        {"days": ["tue"], "start": "00:30", "stop": "00:45", "mission": mission},
    ]
    text = f"time_zone: UTC\nwindows: {windows}\n"
    problems = check_schedule(parse_schedule(text))
    assert [problem.step for problem in problems] == ["windows[1]", "windows[3]"]
    assert all(isinstance(problem, Problem) for problem in problems)
    assert {problem.severity for problem in problems} == {"warning"}
    assert "on_overlap" in str(problems[0])
    windows[1]["on_overlap"] = "preempt"
    windows[3]["on_overlap"] = "skip"
    assert check_schedule(parse_schedule(f"time_zone: UTC\nwindows: {windows}\n")) == []


def test_wall_times_in_the_dst_gap_and_the_repeated_hour() -> None:
    utc = timezone.utc
    spring, autumn = date(2026, 3, 29), date(2026, 10, 25)
    # 02:30 does not exist: the gap's end, 03:00 CEST.
    assert local_instant(spring, time(2, 30), BERLIN) == datetime(2026, 3, 29, 1, 0, tzinfo=utc)
    assert local_instant(spring, time(4), BERLIN) == datetime(2026, 3, 29, 2, 0, tzinfo=utc)
    # 02:30 happens twice: the first one, still CEST.
    assert local_instant(autumn, time(2, 30), BERLIN) == datetime(2026, 10, 25, 0, 30, tzinfo=utc)


def test_occurrences_in_order_with_exclusions_and_midnight() -> None:
    mission = {"mission": "m", "steps": [{"dwell": 1}]}
    plan = parse_schedule(
        "time_zone: Europe/Berlin\nexclude: ['2026-03-24']\nwindows: "
        + str([
            {"days": "weekdays", "start": "13:00", "stop": "18:00", "mission": mission},
            {"days": "weekdays", "start": "08:00", "stop": "12:00", "mission": mission},
            {"days": "weekends", "start": "22:00", "stop": "02:00", "mission": mission},
        ])
    )  # fmt: skip
    found = occurrences(plan, BERLIN, date(2026, 3, 23))
    first = [next(found) for _ in range(12)]
    local = [(o.index, o.start.astimezone(BERLIN).strftime("%a %H:%M"), o.excluded) for o in first]
    assert local[:4] == [
        (1, "Mon 08:00", False), (0, "Mon 13:00", False),
        (1, "Tue 08:00", True), (0, "Tue 13:00", True),
    ]  # fmt: skip
    assert local[10] == (2, "Sat 22:00", False)
    # Sunday 2026-03-29 has no 02:00 (clocks go from 02:00 CET to 03:00 CEST): the gap's end.
    assert first[10].stop.astimezone(BERLIN).strftime("%a %H:%M") == "Sun 03:00"


def test_battery_thresholds_in_percent_read_the_one_voltage_curve() -> None:
    # 25.0 V is 45 % on galileo_async.battery's curve.
    assert battery_charge(25.0) == 45.0
    by_percent = BatteryPolicy(go_charge_below_percent=45.5, resume_at_percent=90)
    assert by_percent.low(25.0)
    assert not by_percent.low(25.1)
    assert not by_percent.charged(26.9)
    assert by_percent.charged(27.8)
    by_volts = BatteryPolicy(go_charge_below_volts=24.0, resume_at_percent=60)
    assert BatteryPolicy.percent(None, 24.0) == battery_charge(24.0)
    assert by_volts.low(23.9)
    assert by_volts.charged(25.5)
