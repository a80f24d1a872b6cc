"""Imports of other plan formats, on files written in those formats.

data/timeTask.json follows the vendor's scheduler, system_monitor (noetic branch)
time_tasks.py: load_tasks() reads mapSwithTasks and autoRunTasks with whichDay,
startTime, stopTime, mapName, pathName (and waitTime, stopPose, loopCount); data/maps/
is its maps folder: MAP/nav_PATH.csv lines "x y z" (utils/nav_task.py) and
MAP/new_nav_PATH.csv lines "x y z theta errorX errorY direction" (AutoRunTask.load_point).
data/nav2_panel_waypoints.yaml is what Nav2's RViz panel saves (nav2_rviz_plugins
nav2_panel.cpp, handleGoalSaver: pose [x, y, z], orientation [w, x, y, z]);
data/nav2_poses.yaml lists geometry_msgs poses with the FollowWaypoints goal's
number_of_loops.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from galileo_async.missions import MissionFileError, parse_mission
from galileo_async.missions.files import dump_mission
from galileo_async.missions.importers import (
    Waypoint,
    detect_format,
    import_nav2,
    import_timetask,
    load_plan,
    parse_nav_points,
    points_from_folder,
    read_nav_points,
)
from galileo_async.missions.model import (
    ChargeStep,
    DwellStep,
    GotoPointStep,
    GotoPoseStep,
    GotoStep,
    LoopStep,
    SwitchMapStep,
)

DATA = Path(__file__).parent / "data"
MAPS = DATA / "maps"


def test_nav_points_files_of_both_kinds() -> None:
    assert read_nav_points(MAPS / "floor1" / "nav_route1.csv") == [
        Waypoint(1.5, 0.0), Waypoint(3.0, 0.0), Waypoint(3.0, 2.0),
    ]  # fmt: skip
    assert read_nav_points(MAPS / "floor2" / "new_nav_lab.csv") == [
        Waypoint(0.5, 0.5, 1.5708), Waypoint(2.0, 1.0, 3.1416),
    ]  # fmt: skip


def test_a_bad_nav_points_line_is_named() -> None:
    with pytest.raises(MissionFileError) as caught:
        parse_nav_points("1 2 0\n\nx y z\n3 nan 0\n", source="nav.csv")
    assert [p.line for p in caught.value.details] == [3, 4]


def test_timetask_gives_a_window_and_a_mission_per_task() -> None:
    plan = load_plan(DATA / "timeTask.json", points=points_from_folder(MAPS))
    assert [(w.kind, w.days, w.start, w.stop, w.stop_pose) for w in plan.windows] == [
        ("mapSwithTasks", (1, 2, 3, 4, 5, 6, 7), "07:30", "07:45", None),
        ("autoRunTasks", (1,), "08:00", "12:00", -1),
        ("autoRunTasks", (1, 2, 3, 4, 5, 6, 7), "13:00", "18:00", 1),
    ]
    assert plan.missions == [window.mission for window in plan.windows]
    switch_only, monday, daily = plan.missions
    assert [type(step) for step in switch_only.steps] == [SwitchMapStep]
    switch, patrol, stop = monday.steps
    assert isinstance(switch, SwitchMapStep)
    assert (switch.switch_map.map, switch.switch_map.path) == ("floor1", "route1")
    assert isinstance(patrol, LoopStep)
    assert patrol.loop.count is None
    assert [(type(s), getattr(s, "goto", None)) for s in patrol.loop.steps] == [
        (GotoStep, 0), (DwellStep, None), (GotoStep, 1), (DwellStep, None), (GotoStep, 2),
        (DwellStep, None),
    ]  # fmt: skip
    assert all(s.dwell == 10 for s in patrol.loop.steps if isinstance(s, DwellStep))
    assert isinstance(stop, ChargeStep)  # stopPose -1: the dock
    _, loop, back = daily.steps
    assert isinstance(loop, LoopStep)
    assert loop.loop.count == 3
    assert [type(s) for s in loop.loop.steps] == [GotoStep, GotoStep]  # waitTime 0: no dwell
    assert isinstance(back, GotoStep)
    assert back.goto == 1
    assert back.name == "stop pose"
    assert plan.notes == []
    for mission in plan.missions:  # each prints as a mission file
        assert parse_mission(dump_mission(mission)) == mission


def test_timetask_as_poses_and_with_one_points_list() -> None:
    text = (DATA / "timeTask.json").read_text(encoding="utf-8")
    points = [Waypoint(1.0, 2.0, 0.5), Waypoint(3.0, 4.0, -0.5)]
    plan = import_timetask(text, points, poses=True)
    loop = plan.missions[2].steps[1]
    assert isinstance(loop, LoopStep)
    first = loop.loop.steps[0]
    assert isinstance(first, GotoPoseStep)
    assert (first.goto_pose.x, first.goto_pose.y, first.goto_pose.theta) == (1.0, 2.0, 0.5)
    stop = plan.missions[2].steps[2]
    assert isinstance(stop, GotoPoseStep)
    assert stop.goto_pose.x == 3.0


def test_a_stop_pose_past_the_path_is_skipped_with_a_note() -> None:
    task = {"whichDay": 3, "startTime": "9:05", "stopTime": "10:00", "mapName": "m",
            "pathName": "p", "waitTime": 1, "stopPose": 5, "loopCount": 1}  # fmt: skip
    plan = import_timetask(json.dumps({"autoRunTasks": [task]}), [Waypoint(0, 0)])
    assert plan.windows[0].start == "09:05"
    assert plan.windows[0].days == (3,)
    assert [type(s) for s in plan.missions[0].steps] == [SwitchMapStep, LoopStep]
    assert "stopPose 5 is past the path's 1 points" in plan.notes[0]


def test_every_bad_task_is_named() -> None:
    good = {"whichDay": 0, "startTime": "08:00", "stopTime": "09:00", "mapName": "m",
            "pathName": "p", "waitTime": 1, "stopPose": -1, "loopCount": 1}  # fmt: skip
    tasks = [
        {**good, "whichDay": 8},
        {**good, "startTime": "25:00"},
        {key: value for key, value in good.items() if key != "waitTime"},
        good,
    ]
    with pytest.raises(MissionFileError) as caught:
        import_timetask(json.dumps({"autoRunTasks": tasks}), [Waypoint(0, 0)], source="t.json")
    assert caught.value.problems == [
        "t.json: autoRunTasks[0]: whichDay 8 is not 0 (every day) or 1-7 (Monday-Sunday)",
        "t.json: autoRunTasks[1]: startTime '25:00' is not HH:MM",
        "t.json: autoRunTasks[2]: missing key 'waitTime'",
    ]


def test_a_path_without_its_points_file_is_named() -> None:
    text = (DATA / "timeTask.json").read_text(encoding="utf-8")
    with pytest.raises(MissionFileError) as caught:
        import_timetask(text, points_from_folder(DATA / "nowhere"))
    assert "no nav_route1.csv or new_nav_route1.csv" in caught.value.problems[0]


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("{", "JSON: Expecting property name"),
        ('{"tasks": []}', "not a timeTask.json"),
    ],
)
def test_what_is_not_a_timetask(text: str, message: str) -> None:
    with pytest.raises(MissionFileError, match=message):
        import_timetask(text, [])


def test_a_timetask_needs_points() -> None:
    with pytest.raises(MissionFileError, match="needs the points of its paths"):
        load_plan(DATA / "timeTask.json")


def test_nav2_panel_file_as_poses_with_headings() -> None:
    mission = load_plan(DATA / "nav2_panel_waypoints.yaml").missions[0]
    assert mission.mission == "nav2_panel_waypoints"
    poses = [(s.name, s.goto_pose) for s in mission.steps if isinstance(s, GotoPoseStep)]
    assert [(name, pose.x, pose.y) for name, pose in poses] == [
        ("waypoint0", 1.5, 0.5), ("waypoint1", 3.0, 0.5), ("waypoint2", 3.0, 2.5),
    ]  # fmt: skip
    assert [pose.theta for _, pose in poses] == pytest.approx([0.0, math.pi / 2, math.pi])


def test_nav2_poses_with_loops_as_points() -> None:
    mission = load_plan(DATA / "nav2_poses.yaml", headings=False).missions[0]
    (loop,) = mission.steps
    assert isinstance(loop, LoopStep)
    assert loop.loop.count == 3
    assert [(s.goto_point.x, s.goto_point.y) for s in loop.loop.steps
            if isinstance(s, GotoPointStep)] == [(1.0, 0.0), (2.0, 1.0)]  # fmt: skip
    once = import_nav2((DATA / "nav2_poses.yaml").read_text(encoding="utf-8"), loops=0)
    assert [type(s) for s in once.steps] == [GotoPoseStep, GotoPoseStep]
    assert once.steps[1].goto_pose.theta == pytest.approx(math.pi)  # type: ignore[union-attr]


def test_every_bad_waypoint_is_named() -> None:
    text = "waypoints:\n  a: {pose: [1]}\n  b: {position: {x: 1}}\n  c: 3\n  d: {pose: [1, 2, 0]}\n"
    with pytest.raises(MissionFileError) as caught:
        import_nav2(text, source="w.yaml")
    assert [p.step for p in caught.value.details] == ["waypoints.a", "waypoints.b", "waypoints.c"]


def test_formats_are_detected_by_content() -> None:
    assert detect_format(DATA / "timeTask.json") == "timetask"
    assert detect_format(DATA / "nav2_panel_waypoints.yaml") == "nav2"
    assert detect_format(DATA / "nav2_poses.yaml") == "nav2"
    assert detect_format(DATA / "every_step.yaml") == "mission"
    plan = load_plan(DATA / "every_step.yaml")
    assert len(plan.missions) == 1
    assert plan.windows == []
