"""The public surface is a contract: pin it, and check every name resolves."""

from __future__ import annotations

import inspect
import json
import subprocess
import sys

import galileo_async as galileo

PUBLIC = {
    "AcceptTimeout", "AngleGoalStatus", "AsyncioRequired", "ChargeStatus", "CommandSuperseded",
    "Connection",
    "ConnectionLost",
    "DiscoveredRobot", "GalileoConnectionError", "GalileoError", "GalileoStatus",
    "GalileoTimeout", "GoalAborted", "GoalCancelled", "GoalError", "GoalRejected",
    "GoalResult", "InvalidArgument", "LinkStale", "MapStatus", "NavStatus", "NotReady",
    "OperationFailed", "OperationTimeout", "PortBusy", "Pose", "Robot", "StatusLayout",
    "TargetStatus",
    "UnconfirmedOperation", "VisualStatus", "WrongEventLoop", "__version__", "connect",
    "discover", "errors", "protocol", "Fleet", "FleetResult", "connect_fleet",
    "GoalStalled", "LinkState",
    "DuplicateVehicle",
    "HttpError", "NotSupported",
    "AuthenticationError", "HttpTimeout",
    "StopReport", "StopUnconfirmed",
}  # fmt: skip

#: DESIGN.md's Robot contract: these names are kept.
ROBOT_COROUTINES = {
    "start_navigation", "stop_navigation", "goto", "goto_point", "add_target",
    "reset_targets", "pause", "resume", "cancel", "rotate_to", "forward", "backward",
    "turn_left", "turn_right", "stop", "start_patrol", "stop_patrol", "set_patrol_dwell",
    "start_mapping", "stop_mapping", "save_map", "update_map", "start_charging",
    "stop_charging", "save_dock", "shutdown_host", "send", "wait_until", "close",
    "wait_link", "zero_speed",
}  # fmt: skip


def test_all_is_pinned() -> None:
    assert set(galileo.__all__) == PUBLIC
    assert len(galileo.__all__) == len(PUBLIC)


def test_every_public_name_resolves() -> None:
    for name in galileo.__all__:
        assert getattr(galileo, name) is not None, name


def test_robot_keeps_the_design_contract() -> None:
    robot = galileo.Robot
    for name in ROBOT_COROUTINES:
        assert inspect.iscoroutinefunction(getattr(robot, name)), name
    listeners = ("add_update_listener", "remove_update_listener", "add_event_listener",
                 "remove_event_listener")  # fmt: skip
    for name in ("statuses", "events", "link_states", *listeners):
        assert callable(getattr(robot, name)), name
    for name in ("status", "link", "link_state"):
        assert isinstance(inspect.getattr_static(robot, name), property), name


def test_errors_are_grouped_under_one_root() -> None:
    for name in galileo.errors.__all__:
        error = getattr(galileo.errors, name)
        assert issubclass(error, galileo.GalileoError), name
    assert issubclass(galileo.InvalidArgument, ValueError)
    assert issubclass(galileo.GalileoTimeout, TimeoutError)
    assert issubclass(galileo.AcceptTimeout, TimeoutError)
    assert issubclass(galileo.GalileoConnectionError, ConnectionError)


def test_dir_lists_the_public_names_and_no_implementation_names() -> None:
    # A fresh interpreter: the lazy names (connect, connect_fleet, Fleet, GalileoStatus) not
    # loaded yet; models (pydantic's) is listed once GalileoStatus has loaded it.
    script = (
        "import json, galileo_async; before = dir(galileo_async); galileo_async.GalileoStatus; "
        "print(json.dumps([before, dir(galileo_async)]))"
    )
    shown, after = json.loads(
        subprocess.run(
            [sys.executable, "-c", script], capture_output=True, text=True, check=True, timeout=60
        ).stdout
    )
    assert set(galileo.__all__) <= set(shown)
    assert shown == sorted(shown)
    for name in ("__doc__", "__name__", "__version__", "__all__", "__path__", "protocol"):
        assert name in shown, name
    assert "models" not in shown
    assert set(after) - set(shown) == {"models"}
    for name in ("TYPE_CHECKING", "Any", "annotations", "importlib", "logging", "types", "_LAZY",
                 "_checks", "__getattr__", "__dir__"):  # fmt: skip
        assert name not in shown, name
    assert all(not name.startswith("_") or name.endswith("__") for name in shown)
