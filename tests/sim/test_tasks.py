"""The simulator's task chains without HTTP: TaskEngine on a RobotModel stepped by frames."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import pytest

from galileo_async.sim.config import SimConfig
from galileo_async.sim.robot_model import FRAME_TIME, RobotModel
from galileo_async.sim.states import CHARGE_FREE, CHARGING, PAUSED, WORKING
from galileo_async.sim.tasks import TaskEngine, TaskError

#: Simulated seconds: a bound on every run expected to end.
LIMIT = 120.0


def engine(**hooks: Any) -> tuple[RobotModel, TaskEngine]:
    model = RobotModel(SimConfig(targets=((1.5, 0.0),)))
    model.open_navigation()
    return model, TaskEngine(model, **hooks)


def run(model: RobotModel, tasks: TaskEngine, until: Callable[[], bool]) -> float:
    """Step frame by frame until ``until()``; the simulated seconds it took."""
    start = model.time
    while not until():
        assert model.time - start < LIMIT, "never happened"
        model.tick()
        tasks.step()
    return model.time - start


def chain(tasks: TaskEngine, *actions: dict[str, Any], loop: bool = False) -> dict[str, Any]:
    return tasks.create({"name": "t", "sub_tasks": list(actions), "loop_flag": loop})


def test_a_new_task_waits_in_the_vendors_shape() -> None:
    _, tasks = engine()
    task = chain(tasks, {"type": "sleep_action", "wait_time": 2})
    assert task["state"] == "WAITTING"
    assert task["current_task"] is None
    assert task["progress"] == 0
    assert task["loop_count"] == 0
    assert task["loop_flag"] is False
    (action,) = task["sub_tasks"]
    assert action == {"type": "sleep_action", "wait_time": 2.0, "state": "WAITTING",
                      "id": action["id"]}  # fmt: skip


def test_nav_action_drives_to_the_pose_then_the_task_is_complete() -> None:
    model, tasks = engine()
    task = chain(tasks, {"type": "nav_action", "x": 1.0, "y": 1.0, "theta": 0.0})
    tasks.start(task["id"])
    assert task["state"] == "WORKING"
    assert task["current_task"]["state"] == "WORKING"
    assert model.target_num_id == -2
    assert model.target_status == WORKING
    run(model, tasks, lambda: task["state"] != "WORKING")
    assert task["state"] == "COMPLETE"
    assert task["progress"] == 100
    assert task["loop_count"] == 1
    assert (model.x, model.y) == (1.0, 1.0)


def test_sleep_action_waits_its_simulated_seconds() -> None:
    model, tasks = engine()
    task = chain(tasks, {"type": "sleep_action", "wait_time": 2.5})
    tasks.start(task["id"])
    took = run(model, tasks, lambda: task["state"] == "COMPLETE")
    assert 2.5 <= took <= 2.5 + 2 * FRAME_TIME


def test_local_move_turns_by_angle_then_drives_distance_backwards() -> None:
    model, tasks = engine()
    task = chain(tasks, {"type": "local_move_action", "distance": -0.5, "angle": math.pi / 2})
    tasks.start(task["id"])
    run(model, tasks, lambda: task["state"] == "COMPLETE")
    assert model.theta == pytest.approx(math.pi / 2, abs=0.01)
    assert (model.x, model.y) == pytest.approx((0.0, -0.5), abs=0.01)
    run(model, tasks, lambda: model.current_v == 0.0 and model.current_w == 0.0)


def test_charge_action_docks_at_its_pose() -> None:
    model, tasks = engine()
    task = chain(tasks, {"type": "charge_action", "x": -2.0, "y": 0.5, "theta": 0.0})
    tasks.start(task["id"])
    run(model, tasks, lambda: task["state"] == "COMPLETE")
    assert model.charge_status == CHARGING
    assert (model.x, model.y) == (-2.0, 0.5)


def test_wait_req_action_waits_for_its_release() -> None:
    model, tasks = engine()
    assert tasks.release_wait() is None  # nothing waits
    task = chain(tasks, {"type": "wait_req_action"}, {"type": "sleep_action", "wait_time": 0})
    tasks.start(task["id"])
    for _ in range(300):
        model.tick()
        tasks.step()
    assert task["state"] == "WORKING"
    assert task["current_task"]["type"] == "wait_req_action"
    released = tasks.release_wait()
    assert released is not None
    assert released["state"] == "COMPLETE"
    run(model, tasks, lambda: task["state"] == "COMPLETE")


def test_callback_action_ends_as_its_request_does() -> None:
    calls: list[tuple[dict[str, Any], Callable[[str | None], None]]] = []
    cancelled: list[str] = []

    def callback(action: dict[str, Any], done: Callable[[str | None], None]) -> Callable[[], None]:
        calls.append((action, done))
        return lambda: cancelled.append(action["id"])

    _model, tasks = engine(callback=callback)
    body = {"type": "callback_action", "url": "http://door.local/open", "data": {"door": 1}}
    ok, failing = chain(tasks, body), chain(tasks, body)
    tasks.start(ok["id"])
    (action, done), = calls  # fmt: skip
    assert (action["method"], action["data"]) == ("POST", {"door": 1})
    done(None)
    assert ok["state"] == "COMPLETE"
    tasks.start(failing["id"])
    calls[1][1]("HTTP 503")
    assert failing["state"] == "ERROR"
    assert failing["current_task"]["state"] == "ERROR"
    assert tasks.errors[failing["current_task"]["id"]] == "HTTP 503"
    stopped = chain(tasks, body)
    tasks.start(stopped["id"])
    tasks.stop(stopped["id"])
    assert cancelled == [stopped["sub_tasks"][0]["id"]]
    calls[2][1](None)  # an answer after the stop changes nothing
    assert stopped["state"] == "CANCELLED"


def test_a_loop_runs_again_and_counts_its_passes_until_the_flag_is_cleared() -> None:
    model, tasks = engine()
    task = chain(tasks, {"type": "sleep_action", "wait_time": 1}, loop=True)
    tasks.start(task["id"])
    run(model, tasks, lambda: task["loop_count"] == 3)
    assert task["state"] == "WORKING"
    tasks.set_loop(task["id"], "false")
    run(model, tasks, lambda: task["state"] == "COMPLETE")
    assert task["loop_count"] == 4


def test_pause_and_resume_mid_nav_action_hold_the_goal() -> None:
    model, tasks = engine()
    task = chain(tasks, {"type": "nav_action", "x": 3.0, "y": 0.0})
    tasks.start(task["id"])
    run(model, tasks, lambda: model.x > 0.5)
    tasks.pause(task["id"])
    assert task["state"] == "PAUSED"
    assert task["current_task"]["state"] == "PAUSED"
    for _ in range(60):
        model.tick()
        tasks.step()
    assert model.target_status == PAUSED
    assert model.current_v == 0.0
    where = model.x
    tasks.resume(task["id"])
    run(model, tasks, lambda: task["state"] == "COMPLETE")
    assert model.x == 3.0 > where


def test_pause_holds_a_sleep_for_as_long_as_it_is_paused() -> None:
    model, tasks = engine()
    task = chain(tasks, {"type": "sleep_action", "wait_time": 2})
    tasks.start(task["id"])
    run(model, tasks, lambda: model.time >= 1.0)
    tasks.pause(task["id"])
    run(model, tasks, lambda: model.time >= 10.0)
    assert task["state"] == "PAUSED"
    tasks.resume(task["id"])
    took = run(model, tasks, lambda: task["state"] == "COMPLETE")
    assert 1.0 - 2 * FRAME_TIME <= took <= 1.0 + 2 * FRAME_TIME


def test_stop_mid_nav_action_cancels_the_goal_and_the_robot_stops() -> None:
    model, tasks = engine()
    task = chain(tasks, {"type": "nav_action", "x": 3.0, "y": 0.0}, {"type": "sleep_action",
                                                                       "wait_time": 0})  # fmt: skip
    tasks.start(task["id"])
    run(model, tasks, lambda: model.x > 0.5)
    tasks.stop(task["id"])
    assert task["state"] == "CANCELLED"
    assert task["current_task"]["state"] == "CANCELLED"
    assert task["sub_tasks"][1]["state"] == "WAITTING"
    run(model, tasks, lambda: model.current_v == 0.0)
    where = model.x
    for _ in range(90):
        model.tick()
        tasks.step()
    assert model.x == where
    assert model.target_status not in (WORKING, PAUSED)


def test_stop_mid_local_move_zeroes_the_wheels() -> None:
    model, tasks = engine()
    task = chain(tasks, {"type": "local_move_action", "distance": 2.0, "angle": 0})
    tasks.start(task["id"])
    run(model, tasks, lambda: model.x > 0.3)
    tasks.stop(task["id"])
    run(model, tasks, lambda: model.current_v == 0.0)
    where = model.x
    for _ in range(90):
        model.tick()
        tasks.step()
    assert model.x == where


def test_stop_mid_charge_action_stops_docking() -> None:
    model, tasks = engine()
    task = chain(tasks, {"type": "charge_action", "x": -3.0, "y": 0.0})
    tasks.start(task["id"])
    run(model, tasks, lambda: model.x < -0.5)
    tasks.stop(task["id"])
    assert model.charge_status == CHARGE_FREE
    assert task["state"] == "CANCELLED"


def test_a_refused_goal_ends_the_task_in_error() -> None:
    model = RobotModel(SimConfig())  # navigation closed: the goal cannot start
    tasks = TaskEngine(model)
    task = chain(tasks, {"type": "nav_action", "x": 1.0, "y": 0.0},
                 {"type": "sleep_action", "wait_time": 0})  # fmt: skip
    tasks.start(task["id"])
    assert task["state"] == "ERROR"
    assert task["current_task"]["state"] == "ERROR"
    assert task["sub_tasks"][1]["state"] == "WAITTING"


def test_a_goal_by_hand_preempts_the_chain() -> None:
    model, tasks = engine()
    task = chain(tasks, {"type": "nav_action", "x": 3.0, "y": 0.0})
    tasks.start(task["id"])
    tasks.preempt()
    assert task["state"] == "CANCELLED"
    assert model.target_status not in (WORKING, PAUSED)


def test_starting_a_task_stops_the_one_that_runs_and_restarts_an_ended_one() -> None:
    model, tasks = engine()
    first = chain(tasks, {"type": "sleep_action", "wait_time": 5})
    second = chain(tasks, {"type": "sleep_action", "wait_time": 0.5})
    tasks.start(first["id"])
    tasks.start(second["id"])
    assert first["state"] == "CANCELLED"
    assert second["state"] == "WORKING"
    run(model, tasks, lambda: second["state"] == "COMPLETE")
    tasks.start(second["id"])
    assert second["state"] == "WORKING"
    assert second["progress"] == 0
    assert second["loop_count"] == 0


def test_an_empty_looping_task_completes_at_once() -> None:
    _, tasks = engine()
    task = chain(tasks, loop=True)
    tasks.start(task["id"])
    assert task["state"] == "COMPLETE"


@pytest.mark.parametrize(
    ("action", "says"),
    [
        ({"type": "fly_action"}, "unknown action type"),
        ({"wait_time": 1}, "unknown action type"),
        ({"type": "upload_map_action", "server_id": "a"}, "not simulated"),
        ({"type": "download_map_action", "server_id": "a", "map_id": "b"}, "not simulated"),
        ({"type": "nav_action", "x": 1}, "nav_action needs y"),
        ({"type": "nav_action", "x": "far", "y": 0}, "x must be a number"),
        ({"type": "nav_action", "x": float("nan"), "y": 0}, "x must be finite"),
        ({"type": "nav_action", "x": True, "y": 0}, "x must be a number"),
        ({"type": "sleep_action", "wait_time": -1}, "wait_time must be >= 0"),
        ({"type": "local_move_action", "distance": 1, "method": 2}, "method must be 0"),
        ({"type": "callback_action", "url": "ftp://x"}, "url must be an http://"),
        ({"type": "callback_action", "url": "http://x", "method": "FLY"}, "method must be one"),
        ({"id": "nope"}, "no action 'nope'"),
        ("sleep", "a sub_task must be an object"),
    ],
)
def test_a_bad_action_is_refused_and_no_task_is_made(action: Any, says: str) -> None:
    _, tasks = engine()
    with pytest.raises(TaskError, match=says):
        chain(tasks, action)
    assert tasks.tasks == {}


def test_unknown_ids_are_404_and_a_running_task_cannot_be_changed() -> None:
    _, tasks = engine()
    for call in (tasks.get, tasks.start, tasks.pause, tasks.resume, tasks.stop, tasks.delete):
        with pytest.raises(TaskError, match="no task 'x'") as info:
            call("x")
        assert info.value.status == 404
    with pytest.raises(TaskError) as info:
        tasks.delete_action("y")
    assert info.value.status == 404
    task = chain(tasks, {"type": "sleep_action", "wait_time": 5})
    tasks.start(task["id"])
    with pytest.raises(TaskError, match="stop it first") as info:
        tasks.update({"id": task["id"], "name": "other"})
    assert info.value.status == 400
    assert task["name"] == "t"
    with pytest.raises(TaskError, match="loop_flag must be true or false"):
        tasks.set_loop(task["id"], "maybe")


def test_actions_by_id_add_change_copy_and_delete() -> None:
    _, tasks = engine()
    auto = tasks.add_action({"type": "sleep_action", "wait_time": 2})
    assert auto["name"] == "auto task"
    assert len(auto["sub_tasks"]) == 1
    action_id = auto["sub_tasks"][0]["id"]
    changed = tasks.update_action({"id": action_id, "wait_time": 3})
    assert changed["wait_time"] == 3.0
    assert changed["id"] == action_id
    into = tasks.add_action({"type": "wait_req_action", "task_id": auto["id"]})
    assert into is auto
    assert [a["type"] for a in auto["sub_tasks"]] == ["sleep_action", "wait_req_action"]
    copied = chain(tasks, {"id": action_id})
    assert copied["sub_tasks"][0]["wait_time"] == 3.0
    assert copied["sub_tasks"][0]["id"] != action_id
    assert tasks.delete_action(action_id) == {"status": "OK"}
    assert len(tasks.actions()) == 2
    assert tasks.update({"id": copied["id"], "loop_flag": True, "name": "n"})["loop_flag"]
    assert tasks.delete(copied["id"]) == {"status": "OK"}
    assert copied["id"] not in tasks.tasks
