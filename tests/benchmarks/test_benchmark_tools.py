"""The breakdown benchmark's stages knock out what they say, and nothing more."""

from __future__ import annotations

import pytest

from benchmarks.breakdown import FLEET_STAGE, STAGES, TASK_STAGE, _spawn

ROBOTS, FRAMES = 20, 6


@pytest.mark.parametrize("stage", STAGES)
def test_breakdown_stages_run_the_path_up_to_their_part(stage: str) -> None:
    figures = _spawn(stage, ROBOTS, FRAMES)
    fed = ROBOTS * FRAMES
    reached = STAGES.index(stage)
    assert figures["us_per_frame"] > 0
    assert figures["decoded"] == (fed if reached >= STAGES.index("decode") else 0)
    assert figures["stored"] == (fed if reached >= STAGES.index("store") else 0)
    # Each consumer takes its link's statuses as they come (a task per link, all waiting),
    # and the one fleet consumer takes every robot once per loop turn (each fed once).
    assert figures["received"] == (fed if stage in (TASK_STAGE, FLEET_STAGE) else 0)
