"""The journal: written at each step, resumed at the step and loop it names, or refused."""

from __future__ import annotations

import asyncio
import json
import time
from pathlib import Path
from typing import Any

import pytest

from galileo_async.missions import (
    Journal,
    Mission,
    MissionEvent,
    MissionRejected,
    StepStarted,
    plan_hash,
    run_mission,
)
from galileo_async.missions.journal import JournalRecord
from galileo_async.protocol import Goto
from galileo_async.testing import simulated_robot

pytestmark = pytest.mark.timeout(60)

PATROL: dict[str, Any] = {
    "mission": "patrol",
    "steps": [
        {"goto": 0},
        {"loop": {"count": 3, "steps": [{"goto": 1}, {"dwell": 5, "name": "rest"}, {"goto": 2}]}},
        {"goto": 3},
    ],
}


def patrol(**changes: Any) -> Mission:
    return Mission.model_validate({**PATROL, **changes})


def temporaries(folder: Path) -> list[Path]:
    return list(folder.glob(".*.tmp"))


def record(path: Path) -> dict[str, Any]:
    data: dict[str, Any] = json.loads(path.read_text(encoding="utf-8"))
    return data


async def test_the_journal_follows_the_run_and_ends_completed(tmp_path: Path) -> None:
    journal = tmp_path / "patrol.json"
    states: list[tuple[str, str | None, dict[str, int]]] = []
    async with simulated_robot() as (robot, _):

        def seen(_: object) -> None:
            data = record(journal)
            states.append((data["state"], data["path"], data["loops"]))

        await run_mission(robot, patrol(), journal=journal, on_progress=seen)
    final = record(journal)
    assert final["state"] == "completed"
    assert final["plan"] == plan_hash(patrol())
    assert final["mission"] == "patrol"
    assert ("started", "steps[1].loop.steps[1]", {"steps[1]": 1}) in states
    assert ("ended", "steps[1].loop.steps[2]", {"steps[1]": 2}) in states
    assert temporaries(tmp_path) == []  # written through a temporary file, then replaced


async def test_resume_continues_at_the_step_and_loop_where_the_run_stopped(
    tmp_path: Path,
) -> None:
    journal = tmp_path / "patrol.json"
    resting = asyncio.Event()

    def second_rest(event: MissionEvent) -> None:
        if isinstance(event, StepStarted) and event.name == "rest" and event.loops["steps[1]"] == 2:
            resting.set()

    async with simulated_robot() as (robot, device):
        running = asyncio.ensure_future(
            run_mission(robot, patrol(), journal=journal, on_progress=second_rest)
        )
        await resting.wait()
        await asyncio.sleep(1)  # into the second turn's dwell
        assert record(journal)["loops"] == {"steps[1]": 1}  # 0-based in the file
        await robot.stop()
        first = await running
        assert first.ending == "stopped"
        assert record(journal)["state"] == "stopped"
        device.clear()
        second = await run_mission(robot, patrol(), journal=journal, resume=True)
        assert device.received(Goto) == [Goto(2), Goto(1), Goto(2), Goto(3)]
    assert second.ending == "completed"
    assert second.resumed_at == "steps[1].loop.steps[1]"
    assert [(s.path, s.loops) for s in second.steps] == [
        ("steps[1].loop.steps[1]", {"steps[1]": 2}),
        ("steps[1].loop.steps[2]", {"steps[1]": 2}),
        ("steps[1].loop.steps[0]", {"steps[1]": 3}),
        ("steps[1].loop.steps[1]", {"steps[1]": 3}),
        ("steps[1].loop.steps[2]", {"steps[1]": 3}),
        ("steps[2]", {}),
    ]


async def test_resume_after_a_step_that_ended_starts_at_the_next(tmp_path: Path) -> None:
    journal = tmp_path / "patrol.json"
    plan = patrol()
    Journal(journal).write(_record(plan, "ended", "steps[1].loop.steps[2]", {"steps[1]": 2}))
    async with simulated_robot() as (robot, device):
        report = await run_mission(robot, plan, journal=journal, resume=True)
        assert device.received(Goto) == [Goto(3)]
    assert [s.path for s in report.steps] == ["steps[2]"]


async def test_resume_without_a_journal_file_starts_at_the_beginning(tmp_path: Path) -> None:
    async with simulated_robot() as (robot, _):
        report = await run_mission(
            robot, patrol(steps=[{"goto": 1}]), journal=tmp_path / "new.json", resume=True
        )
    assert [s.path for s in report.steps] == ["steps[0]"]
    assert report.resumed_at is None


@pytest.mark.parametrize("why", ["changed", "completed", "old", "other mission"])
async def test_resume_refuses_a_journal_that_does_not_match(tmp_path: Path, why: str) -> None:
    journal = tmp_path / "patrol.json"
    plan = patrol()
    written = _record(plan, "ended", "steps[0]", {})
    if why == "completed":
        written = _record(plan, "completed", "steps[2]", {})
    elif why == "old":
        written = _record(plan, "stopped", "steps[0]", {}, at=time.time() - 25 * 3600)
    elif why == "other mission":
        written = _record(patrol(mission="night"), "stopped", "steps[0]", {})
    Journal(journal).write(written)
    run = patrol(steps=[{"goto": 0}, {"goto": 5}]) if why == "changed" else plan
    expected = {
        "changed": "the plan changed since it was written",
        "completed": "the mission completed; nothing to resume",
        "old": "25.0 h old (more than 24 h)",
        "other mission": "is of mission 'night'",
    }[why]
    async with simulated_robot() as (robot, device):
        device.clear()
        with pytest.raises(MissionRejected, match="rejected") as info:
            await run_mission(robot, run, journal=journal, resume=True)
        assert device.commands == []
    assert len(info.value.problems) == 1
    assert expected in info.value.problems[0]
    assert record(journal) == json.loads(json.dumps(written.__dict__))  # left as it was


async def test_resume_needs_a_journal() -> None:
    async with simulated_robot() as (robot, _):
        with pytest.raises(MissionRejected, match="resume needs a journal"):
            await run_mission(robot, patrol(), resume=True)


async def test_a_journal_that_is_not_one_is_refused(tmp_path: Path) -> None:
    journal = tmp_path / "patrol.json"
    journal.write_text("{}", encoding="utf-8")
    async with simulated_robot() as (robot, _):
        with pytest.raises(MissionRejected, match="not a mission journal"):
            await run_mission(robot, patrol(), journal=journal, resume=True)


def _record(
    plan: Mission, state: str, path: str, loops: dict[str, int], at: float | None = None
) -> JournalRecord:
    return JournalRecord(plan.mission, plan_hash(plan), state, path, loops, at or time.time())


async def test_a_journal_in_a_folder_that_does_not_exist_is_refused(tmp_path: Path) -> None:
    async with simulated_robot() as (robot, device):
        device.clear()
        with pytest.raises(MissionRejected, match="no folder"):
            await run_mission(robot, patrol(), journal=tmp_path / "nowhere" / "j.json")
        assert device.commands == []


async def test_robot_run_mission_takes_the_journals_max_age(tmp_path: Path) -> None:
    journal = tmp_path / "patrol.json"
    Journal(journal).write(_record(patrol(), "stopped", "steps[0]", {}, at=time.time() - 7200))
    async with simulated_robot() as (robot, _):
        with pytest.raises(MissionRejected, match=r"2\.0 h old \(more than 1 h\)"):
            await robot.run_mission(patrol(), journal=journal, resume=True, journal_max_age=3600)
        report = await robot.run_mission(patrol(), journal=journal, resume=True)
    assert report.resumed_at == "steps[0]"
