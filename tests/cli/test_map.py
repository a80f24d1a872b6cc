"""The map panel's model (bounds, trail, targets from every source) and its drawing."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from rich.console import Console

from galileo_async.cli.map_model import (
    MIN_SPAN,
    TRAIL_SECONDS,
    MapModel,
    known_targets,
    load_targets_csv,
)
from galileo_async.cli.map_render import ARROWS, arrow_for, map_panel, save_svg
from galileo_async.errors import InvalidArgument
from galileo_async.models import GalileoStatus
from tests.support.fake_device import make_status


def at(x: float, y: float, theta: float = 0.0, **fields: object) -> GalileoStatus:
    # Navigation open: no goal runs while it is closed (docs/protocol.md §2.a).
    pose = {"current_pose_x": x, "current_pose_y": y, "current_angle": theta}
    return make_status(**({"nav_status": 1} | pose | fields))


class Clock:
    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def test_bounds_fit_everything_with_a_minimum_span() -> None:
    model = MapModel()
    empty = model.bounds()
    assert empty.width == pytest.approx(MIN_SPAN)
    model.update("a", at(10.0, -2.0))
    model.update("b", at(30.0, 4.0))
    model.add_target(0, -5.0, 0.0, "map")
    bounds = model.bounds(margin=0.0)
    assert (bounds.x_min, bounds.x_max) == (-5.0, 30.0)
    assert bounds.y_min == -2.0
    assert bounds.y_max == 4.0


def test_unknown_pose_is_not_drawn() -> None:
    model = MapModel()
    model.update("a", at(-1.0, -1.0, -1.0))
    assert model.robots == {}


def test_trail_keeps_the_last_minute_of_movement_only() -> None:
    clock = Clock()
    model = MapModel(clock=clock)
    for step in range(100):
        clock.now = float(step)
        model.update("a", at(step * 0.1, 0.0))
    trail = model.robots["a"].trail
    assert trail[-1] == (99.0, pytest.approx(9.9), 0.0)
    assert trail[0][0] >= 99.0 - TRAIL_SECONDS
    clock.now = 100.0
    model.update("a", at(9.9, 0.0))  # standing still adds no point
    assert trail[-1][0] == 99.0


def test_targets_learned_on_arrival_and_sources_ranked() -> None:
    model = MapModel()
    model.update("a", at(2.0, 1.0, target_num_id=4, target_status=1, target_distance=0.5))
    assert model.goals() == {4}
    assert 4 not in model.targets
    model.update("a", at(2.5, 1.0, target_num_id=4, target_status=0, target_distance=0.004))
    assert model.targets[4].source == "learned"
    assert (model.targets[4].x, model.targets[4].y) == (2.5, 1.0)
    assert model.goals() == set()
    # A free goal far from the target is not an arrival.
    model.update("a", at(0.0, 0.0, target_num_id=5, target_status=0, target_distance=3.0))
    assert 5 not in model.targets
    model.add_target(4, 2.0, 1.0, "file")  # a file wins over what was learned
    model.update("a", at(2.6, 1.0, target_num_id=4, target_status=0, target_distance=0.0))
    assert model.targets[4].source == "file"
    with pytest.raises(InvalidArgument, match="source"):
        model.add_target(1, 0, 0, "guess")


def test_the_map_learns_the_arrivals_goto_and_events_report() -> None:
    # One rule (transitions.goal_step): free within arrive_tolerance of the last valid
    # distance; -1 at the end keeps the last valid one (docs/protocol.md §1).
    model = MapModel()
    for target_id, end in ((1, 0.2), (2, -1.0)):
        model.update("a", at(1.0, 1.0, target_num_id=target_id, target_status=1, target_distance=1))
        model.update(
            "a", at(2.0, 2.0, target_num_id=target_id, target_status=1, target_distance=0.1)
        )
        model.update(
            "a", at(2.0, 2.0, target_num_id=target_id, target_status=0, target_distance=end)
        )
    assert sorted(model.targets) == [1, 2]
    # Free near a target without having driven there is no arrival seen.
    model.update("b", at(5.0, 5.0, target_num_id=3, target_status=0, target_distance=0.0))
    assert 3 not in model.targets


def test_an_arrival_behind_a_target_status_newer_firmware_adds_is_learned() -> None:
    # The map follows goals with the same machine as events(): an unknown value (7) is
    # no information, so the arrival after it is judged against the working frame.
    model = MapModel()
    model.update("a", at(1.0, 1.0, target_num_id=3, target_status=1, target_distance=0.2))
    model.update("a", at(1.5, 1.0, target_num_id=3, target_status=7, target_distance=0.1))
    model.update("a", at(1.6, 1.0, target_num_id=3, target_status=0, target_distance=0.0))
    assert model.targets[3].source == "learned"
    assert (model.targets[3].x, model.targets[3].y) == (1.6, 1.0)


def test_targets_csv(tmp_path: Path) -> None:
    path = tmp_path / "targets.csv"
    path.write_text("id,x,y\n0, 1.5, -2\n# a comment\n\n7,3,4\n")
    assert load_targets_csv(path) == [(0, 1.5, -2.0), (7, 3.0, 4.0)]
    for text, message in (("1,2\n", ":1: expected 3 columns"), ("x,1,2\n", ":1:"),
                          ("0,0,0\n300,1,1\n", ":2: id must be 0..255"),
                          ("0,nan,1\n", "finite")):  # fmt: skip
        path.write_text(text)
        with pytest.raises(InvalidArgument, match=message):
            load_targets_csv(path)
    with pytest.raises(InvalidArgument, match="cannot read"):
        load_targets_csv(tmp_path / "missing.csv")


def test_known_targets_of_a_simulator_and_a_file(tmp_path: Path) -> None:
    path = tmp_path / "targets.csv"
    path.write_text("9,5,5\n")
    model = known_targets(["sim://?targets=1,2;3,4", "socket://127.0.0.1:9"], path)
    assert {t.target_id: (t.x, t.y, t.source) for t in model.targets.values()} == {
        0: (1.0, 2.0, "map"), 1: (3.0, 4.0, "map"), 9: (5.0, 5.0, "file"),
    }  # fmt: skip


@pytest.mark.parametrize(("theta", "arrow"), [(0.0, "→"), (math.pi / 2, "↑"), (math.pi, "←"),
                                              (-math.pi / 2, "↓"), (math.pi / 4, "↗")])  # fmt: skip
def test_arrow_points_along_the_heading(theta: float, arrow: str) -> None:
    assert arrow_for(theta) == arrow


def draw(model: MapModel, width: int = 60, rows: int = 10) -> list[str]:
    console = Console(width=width, record=True, color_system=None)
    console.print(map_panel(model, rows))
    return console.export_text().splitlines()[1:-1]


def test_drawing_places_robots_targets_and_highlights_the_goal() -> None:
    model = MapModel()
    model.add_target(3, 4.0, 0.0, "map")
    model.update("r", at(-4.0, 0.0, 0.0, target_num_id=3, target_status=1, target_distance=8))
    lines = draw(model)
    assert len(lines) == 10
    robot_line = next(line for line in lines if "→ r" in line)
    assert robot_line.index("→") < robot_line.index("◆3")  # west of the target, same row
    console = Console(width=60, record=True, force_terminal=True, color_system="truecolor")
    console.print(map_panel(model, 10))
    assert "\x1b[" in console.export_text(styles=True)  # the goal is styled


def test_north_is_up() -> None:
    model = MapModel()
    model.update("n", at(0.0, 5.0, math.pi / 2))
    model.update("s", at(0.0, -5.0, -math.pi / 2))
    lines = draw(model)
    north = next(i for i, line in enumerate(lines) if "↑ n" in line)
    south = next(i for i, line in enumerate(lines) if "↓ s" in line)
    assert north < south


def test_a_thousand_robots_draw_without_labels() -> None:
    model = MapModel()
    for index in range(1000):
        model.update(f"r{index}", at(index % 40, index // 40, 0.0))
    text = "\n".join(draw(model, 100, 20))
    assert "r5" not in text
    assert sum(text.count(arrow) for arrow in ARROWS) > 100


def test_svg(tmp_path: Path) -> None:
    path = tmp_path / "map.svg"
    save_svg(map_panel(MapModel()), path)
    assert path.read_text().startswith("<svg")
