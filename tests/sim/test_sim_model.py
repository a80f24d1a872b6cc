"""The simulated robot's state machines, stepped in simulated time (no event loop)."""

from __future__ import annotations

import math
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from galileo_async.errors import InvalidArgument
from galileo_async.models import GalileoStatus, StatusLayout
from galileo_async.protocol import (
    UDP_LAYOUTS,
    StatusDecoder,
    StatusEncoder,
    UdpStatusDecoder,
    encode_status,
)
from galileo_async.protocol import commands as c
from galileo_async.sim import FRAME_RATE, FrameEncoder, RobotModel, SimConfig, parse_sim_url
from galileo_async.transitions import at_target

FIRMWARES = ["real", "document"]
TARGETS = ((2.0, 0.0), (0.0, 3.0), (-2.0, -1.0))


#: Free within this many metres: the simulator lands a goal it drove on its target.
ARRIVED = 0.01


def arrived(status: GalileoStatus) -> bool:
    """Free within 1 cm of the target: where the simulator ends a goal it drove."""
    return at_target(status, ARRIVED)


def make(firmware: str = "real", **options: Any) -> RobotModel:
    options.setdefault("targets", TARGETS)
    return RobotModel(SimConfig().replace(firmware=firmware, **options))


def run(model: RobotModel, seconds: float) -> None:
    for _ in range(round(seconds * FRAME_RATE)):
        model.tick()


def run_until(model: RobotModel, predicate: Any, limit: float = 60.0) -> float:
    """Step until predicate(model) holds; returns the simulated seconds it took."""
    start = model.time
    while not predicate(model):
        assert model.time - start < limit, "condition never reached"
        model.tick()
    return model.time - start


def navigating(firmware: str = "real", **options: Any) -> RobotModel:
    model = make(firmware, **options)
    model.submit(c.StartNavigation())
    run_until(model, lambda m: m.visual_initialised and not m.busy)
    return model


def status(model: RobotModel) -> Any:
    return model.status()


# ---------------------------------------------------------------- defaults and frames
def test_defaults_before_navigation() -> None:
    model = make()
    model.tick()
    s = status(model)
    assert s.time_stamp == 1
    assert (s.target_num_id, s.target_status, s.angle_goal_status) == (-1, -1, -1)
    assert s.target_distance == -1.0
    assert s.nav_status == 0
    assert s.busy_status == 0
    assert s.pose is None  # unknown before the visual system is initialised
    assert s.power == 25.0
    model.tick()
    assert status(model).time_stamp == 2


@pytest.mark.parametrize("layout", [lay for lay in StatusLayout if lay is not StatusLayout.ROS])
def test_frame_encoder_matches_encode_status(layout: StatusLayout) -> None:
    model = navigating()
    model.submit(c.Goto(1))
    encoder = FrameEncoder(layout)
    for _ in range(40):
        model.tick()
        frame = encoder.encode(model.wire_values(), model.time_stamp)
        assert frame == encode_status(model.status(), layout)
        if layout in UDP_LAYOUTS:  # one frame per datagram
            decoded = UdpStatusDecoder().feed(frame)
        else:  # a decoder needs the next header to confirm unterminated frames
            decoded = StatusDecoder(layout).feed(frame + frame[:3])
        assert decoded
        assert decoded[0].target_num_id == 1
    same = encoder.encode(model.wire_values(), model.time_stamp + 1)
    assert same == encode_status(
        model.status().model_copy(update={"time_stamp": model.time_stamp + 1}), layout
    )


def test_the_simulator_sends_frames_with_the_protocols_encoder() -> None:
    assert issubclass(FrameEncoder, StatusEncoder)
    own = {name for name in vars(FrameEncoder) if not name.startswith("__")}
    assert own == set()  # no encoding of its own: the field order only


# ---------------------------------------------------------------- navigation start/stop
@pytest.mark.parametrize("firmware", FIRMWARES)
def test_start_navigation_initialises_visual_and_is_busy(firmware: str) -> None:
    model = make(firmware, visual_init_time=2.0, busy_on_start=1.0)
    model.submit(c.StartNavigation())
    model.tick()
    s = status(model)
    assert s.nav_status == 1
    assert s.visual_status == 0
    assert s.busy_status == 1
    assert s.pose is None
    assert run_until(model, lambda m: not m.busy) == pytest.approx(1.0, abs=0.05)
    assert run_until(model, lambda m: m.visual_status == 1) == pytest.approx(1.0, abs=0.05)
    pose = status(model).pose
    assert pose is not None
    assert (pose.x, pose.y) == (0.0, 0.0)


def test_real_firmware_ignores_restart_within_window() -> None:
    model = navigating("real", start_ignore_time=10.0)
    model.submit(c.StopNavigation())
    model.tick()
    assert status(model).nav_status == 0
    model.submit(c.StartNavigation())  # ~3 s after the previous start: ignored
    model.tick()
    assert status(model).nav_status == 0
    run(model, 8.0)
    model.submit(c.StartNavigation())
    model.tick()
    assert status(model).nav_status == 1


def test_document_mode_restarts_at_once() -> None:
    model = navigating("document")
    model.submit(c.StopNavigation())
    model.submit(c.StartNavigation())
    model.tick()
    assert status(model).nav_status == 1
    assert status(model).visual_status == 0


@pytest.mark.parametrize("firmware", FIRMWARES)
def test_stop_navigation_stops_patrol_goal_and_speed(firmware: str) -> None:
    model = navigating(firmware)
    model.submit(c.StartPatrol())
    run(model, 1.0)
    assert model.loop_status == 1
    assert model.target_status == 1
    assert model.current_v > 0
    model.submit(c.StopNavigation())
    model.tick()
    s = status(model)
    assert (s.nav_status, s.loop_status, s.target_status) == (0, 0, 0)
    assert s.current_speed_x == 0.0
    assert s.control_speed_x == 0.0
    assert s.pose is None
    expected_id = -1 if firmware == "real" else 0
    assert s.target_num_id == expected_id


# ---------------------------------------------------------------- goals
@pytest.mark.parametrize("firmware", FIRMWARES)
def test_goal_ignored_before_visual_initialised(firmware: str) -> None:
    model = make(firmware, visual_init_time=5.0, busy_on_start=0.0)
    model.submit(c.Goto(0))
    model.submit(c.StartNavigation())
    model.tick()
    model.submit(c.Goto(0))
    model.tick()
    assert (model.target_status, model.target_num_id) == (-1, -1)


@pytest.mark.parametrize("firmware", FIRMWARES)
def test_goal_drives_and_arrives(firmware: str) -> None:
    model = navigating(firmware)
    model.submit(c.Goto(1))
    model.tick()
    s = status(model)
    assert (s.target_num_id, s.target_status) == (1, 1)
    assert s.target_distance == pytest.approx(3.0, abs=0.05)
    assert s.angle_goal_status == (0 if firmware == "real" else -1)
    seconds = run_until(model, lambda m: m.target_status == 0)
    assert 3.0 / 0.8 < seconds < 10.0  # max speed 0.8 m/s, plus turning
    s = status(model)
    assert arrived(s)
    assert s.target_distance == 0.0
    assert (s.current_pose_x, s.current_pose_y) == pytest.approx(TARGETS[1])
    assert s.current_speed_x == 0.0
    assert s.control_speed_x == 0.0
    assert s.angle_goal_status == (1 if firmware == "real" else -1)


def test_speed_limits_hold_while_driving() -> None:
    model = navigating()
    model.submit(c.Goto(2))
    while model.target_status == 1:
        model.tick()
        assert abs(model.current_v) <= 0.8 + 1e-9
        assert abs(model.current_w) <= 1.5 + 1e-9


def test_invalid_goal_real_firmware_reports_minus_one_and_keeps_id() -> None:
    model = navigating("real")
    model.submit(c.Goto(0))
    run_until(model, lambda m: m.target_status == 0)
    model.submit(c.Goto(len(TARGETS)))
    model.tick()
    s = status(model)
    assert (s.target_status, s.target_num_id) == (-1, 0)
    assert s.goal_failed


def test_invalid_goal_document_reports_error_and_id() -> None:
    model = navigating("document")
    model.submit(c.Goto(0))
    model.submit(c.Goto(7))
    model.tick()
    s = status(model)
    assert (s.target_status, s.target_num_id) == (3, 7)
    assert model.current_v == 0.0


@pytest.mark.parametrize("firmware", FIRMWARES)
def test_new_goal_cancels_running_one(firmware: str) -> None:
    model = navigating(firmware)
    model.submit(c.Goto(1))
    run(model, 1.0)
    model.submit(c.Goto(2))
    model.tick()
    assert (model.target_num_id, model.target_status) == (2, 1)
    run_until(model, lambda m: m.target_status == 0)
    assert (model.x, model.y) == pytest.approx(TARGETS[2])


@pytest.mark.parametrize("firmware", FIRMWARES)
def test_pause_resume_cancel_only_in_valid_states(firmware: str) -> None:
    model = navigating(firmware)
    for command in (c.Pause(), c.Resume()):
        model.submit(command)  # no goal yet: all ignored
        model.tick()
        assert (model.target_status, model.target_num_id) == (-1, -1)
    model.submit(c.Cancel())  # the -1 default is not free: a cancel frees it
    model.tick()
    assert (model.target_status, model.target_num_id) == (0, -1)
    model.submit(c.Goto(1))
    model.submit(c.Resume())  # not paused: ignored
    run(model, 1.0)
    assert model.target_status == 1
    model.submit(c.Pause())
    run(model, 1.0)
    assert model.target_status == 2
    assert model.current_v == 0.0
    where = (model.x, model.y)
    model.submit(c.Pause())  # already paused: ignored
    run(model, 1.0)
    assert (model.x, model.y) == where
    assert model.target_status == 2
    model.submit(c.Resume())
    run(model, 0.5)
    assert model.target_status == 1
    assert model.current_v > 0
    model.submit(c.Cancel())
    model.tick()
    assert model.target_status == 0
    assert model.current_v == 0.0
    assert model.target_num_id == (-1 if firmware == "real" else 1)
    model.submit(c.Cancel())  # free: ignored
    model.tick()
    assert model.target_status == 0


@pytest.mark.parametrize("firmware", FIRMWARES)
def test_dynamic_targets(firmware: str) -> None:
    model = navigating(firmware)
    model.submit(c.AddTarget(1.0, 1.0))
    model.submit(c.AddTarget(-1.5, 0.5))
    assert model.targets[3:] == [(1.0, 1.0), (-1.5, 0.5)]
    model.submit(c.Goto(4))
    run_until(model, lambda m: m.target_status == 0)
    assert (model.x, model.y) == pytest.approx((-1.5, 0.5))
    model.submit(c.ResetTargets())
    assert model.targets == list(TARGETS)
    model.submit(c.Goto(3))
    model.tick()
    assert model.target_status == (-1 if firmware == "real" else 3)


# ---------------------------------------------------------------- teleop and rotate
@pytest.mark.parametrize("firmware", FIRMWARES)
def test_teleop_persists_until_stop(firmware: str) -> None:
    model = make(firmware)  # works without navigation
    model.submit(c.Forward(50))
    run(model, 3.0)
    assert model.control_v == pytest.approx(0.4)
    assert model.current_v == pytest.approx(0.4)
    assert model.x > 0.8
    model.submit(c.TurnLeft(100))  # forward + turn: an arc
    run(model, 1.0)
    assert model.current_v == pytest.approx(0.4)
    assert model.current_w == pytest.approx(1.5)
    assert model.y > 0.0
    model.submit(c.TurnRight(20))
    model.tick()
    assert model.control_w == pytest.approx(-0.3)
    model.submit(c.Backward(10))
    model.tick()
    assert model.control_v == pytest.approx(-0.08)
    model.submit(c.Stop(100))
    model.tick()
    assert (model.current_v, model.current_w) == (0.0, 0.0)
    assert (model.target_status, model.target_num_id) == (-1, -1)


def test_cmd_vel_timeout_models_a_chassis_watchdog() -> None:
    held = make()  # None: the speed holds, as on chassis builds without a watchdog
    held.submit(c.Forward(50))
    run(held, 30.0)
    assert held.control_v == pytest.approx(0.4)
    model = make(cmd_vel_timeout=3.0)  # chitu-noetic: stops 3 s after the last command
    model.submit(c.Forward(50))
    model.submit(c.TurnLeft(20))
    run(model, 2.0)
    model.submit(c.Forward(50))  # a keep-alive restarts the watchdog's 3 s
    run(model, 2.5)
    assert (model.control_v, model.control_w) == (pytest.approx(0.4), pytest.approx(0.3))
    run(model, 1.0)
    assert (model.control_v, model.control_w) == (0.0, 0.0)
    assert parse_sim_url("sim://?cmd_vel_timeout=1.5").cmd_vel_timeout == 1.5
    with pytest.raises(InvalidArgument, match="cmd_vel_timeout"):
        SimConfig(cmd_vel_timeout=-1.0)


def test_cmd_vel_timeout_leaves_a_goal_alone() -> None:
    model = navigating(cmd_vel_timeout=0.5)
    model.submit(c.Goto(1))
    run(model, 2.0)
    assert model.target_status == 1
    assert model.current_v > 0


def test_teleop_does_not_change_goal_state() -> None:
    model = navigating()
    model.submit(c.Goto(1))
    model.submit(c.Pause())
    model.submit(c.Forward(100))
    run(model, 0.5)
    assert model.target_status == 2
    assert model.current_v > 0
    model.submit(c.Stop())
    model.submit(c.Resume())
    run_until(model, lambda m: m.target_status == 0)
    assert model.target_num_id == 1


def test_document_mode_rotation_to_the_current_heading_shows_not_done_first() -> None:
    model = navigating("document")
    model.submit(c.RotateTo(0))  # already facing 0°
    model.tick()
    assert status(model).angle_goal_status == 0  # a host can see the new rotation start
    model.tick()
    assert status(model).angle_goal_status == 1


def test_real_firmware_ignores_rotate() -> None:
    model = navigating("real")
    model.submit(c.RotateTo(90))
    run(model, 3.0)
    assert model.theta == 0.0
    assert status(model).angle_goal_status == -1  # no goal yet: derived from target_status -1


def test_document_mode_rotates() -> None:
    model = navigating("document")
    model.submit(c.RotateTo(-90))
    model.tick()
    assert status(model).angle_goal_status == 0
    seconds = run_until(model, lambda m: m.rotate_status == 1)
    ramp_up = 1.5 / 3.0 / 2  # time lost reaching 1.5 rad/s at 3 rad/s²
    assert seconds == pytest.approx(math.pi / 2 / 1.5 + ramp_up, abs=0.1)
    assert model.theta == pytest.approx(-math.pi / 2)
    model.submit(c.Goto(0))
    model.submit(c.RotateTo(10))  # goal working: error
    model.tick()
    assert status(model).angle_goal_status == 2


# ---------------------------------------------------------------- patrol
@pytest.mark.parametrize("firmware", FIRMWARES)
def test_patrol_loops_with_dwell(firmware: str) -> None:
    model = make(firmware, patrol_dwell=2.0)
    model.submit(c.StartPatrol())  # needs navigation
    model.tick()
    assert model.loop_status == 0
    model = navigating(firmware, patrol_dwell=2.0)
    model.submit(c.StartPatrol())
    model.tick()
    assert (model.loop_status, model.target_num_id, model.target_status) == (1, 0, 1)
    visited = []
    for _ in range(len(TARGETS) + 1):
        run_until(model, lambda m: m.target_status == 0)
        visited.append(model.target_num_id)
        dwell = run_until(model, lambda m: m.target_status == 1)
        assert dwell == pytest.approx(2.0, abs=0.05)
    assert visited == [0, 1, 2, 0]


def test_patrol_dwell_command_real_firmware_also_starts() -> None:
    model = navigating("real")
    model.submit(c.SetPatrolDwell(7))
    model.tick()
    assert model.patrol_dwell == 7.0
    assert model.loop_status == 1
    model.submit(c.StopPatrol())
    model.tick()
    assert model.loop_status == 0
    assert model.target_status == 0
    assert model.nav_status == 1


def test_patrol_document_mode_dwell_only_and_m6_ignored() -> None:
    model = navigating("document")
    model.submit(c.SetPatrolDwell(7))
    model.tick()
    assert model.patrol_dwell == 7.0
    assert model.loop_status == 0
    model.submit(c.StartPatrol())
    model.submit(c.StopPatrol())
    model.tick()
    assert model.loop_status == 1
    model.submit(c.StopNavigation())
    model.tick()
    assert model.loop_status == 0


def test_goto_by_hand_ends_patrol() -> None:
    model = navigating()
    model.submit(c.StartPatrol())
    model.submit(c.Goto(2))
    model.tick()
    assert model.loop_status == 0
    assert model.target_num_id == 2


# ---------------------------------------------------------------- mapping
@pytest.mark.parametrize("firmware", FIRMWARES)
def test_mapping_cycle(firmware: str) -> None:
    model = navigating(firmware, busy_on_map_stop=2.0, busy_on_save=1.0)
    model.submit(c.StartMapping())
    model.tick()
    assert (model.map_status, model.nav_status) == (1, 0)
    assert status(model).pose is not None  # mapping tracks the pose
    model.submit(c.StartNavigation())  # refused while mapping
    model.tick()
    assert model.nav_status == 0
    model.submit(c.StopMapping())
    model.tick()
    assert model.map_status == 0
    assert model.busy
    assert run_until(model, lambda m: not m.busy) == pytest.approx(2.0, abs=0.05)
    model.submit(c.SaveMap())
    model.tick()
    assert model.busy
    run_until(model, lambda m: not m.busy)
    model.submit(c.UpdateMap())
    model.tick()
    assert model.map_status == 1


def test_save_map_ignored_option() -> None:
    model = make(ignore_save_map=True)
    model.submit(c.SaveMap())
    model.tick()
    assert not model.busy


# ---------------------------------------------------------------- charging, power, misc
@pytest.mark.parametrize("firmware", FIRMWARES)
def test_charging_cycle(firmware: str) -> None:
    model = navigating(firmware, dock=(-1.0, 0.0), docking_time=2.0, power=27.0, charge_rate=0.5)
    seen = [model.charge_status]
    model.submit(c.StartCharging())
    while model.charge_status != 2:
        model.tick()
        if model.charge_status != seen[-1]:
            seen.append(model.charge_status)
        assert model.time < 60
    assert seen == [0, 3, 4, 1, 2]
    assert (model.x, model.y) == (-1.0, 0.0)
    assert model.power == pytest.approx(28.0)
    model.submit(c.StopCharging())
    model.tick()
    assert model.charge_status == 0
    model.submit(c.Forward(100))
    run(model, 1.0)
    model.submit(c.SaveDock())
    assert model.dock == (model.x, model.y)


def test_power_drains_slowly() -> None:
    model = make(power=25.0, power_drain=0.01)
    run(model, 100.0)
    assert status(model).power == pytest.approx(24.0, abs=0.01)


def test_greeting_switch() -> None:
    model = make()
    model.submit(c.Greeting(False))
    assert model.greeting is False
    model.submit(c.Greeting(True))
    assert model.greeting is True


def test_unknown_payload_is_ignored() -> None:
    model = navigating()
    before = model.wire_values()
    model.submit(c.RawCommand(b"zz"))
    assert model.wire_values() == before


def test_shutdown_stops_everything() -> None:
    model = navigating()
    model.submit(c.Forward(100))
    model.submit(c.ShutdownHost())
    stamp = model.time_stamp
    model.tick()
    model.submit(c.Goto(0))
    assert model.shutdown
    assert model.time_stamp == stamp
    assert model.current_v == 0.0
    assert model.target_status == -1


# ---------------------------------------------------------------- busy queue
@pytest.mark.parametrize("firmware", FIRMWARES)
def test_commands_wait_while_busy(firmware: str) -> None:
    model = navigating(firmware, visual_init_time=0.5, busy_on_start=0.0)
    model.set_busy(3.0)
    model.submit(c.Goto(0))
    model.submit(c.AddTarget(5.0, 5.0))
    run(model, 2.0)
    assert model.pending == 2
    assert model.target_status == -1
    assert len(model.targets) == 3
    run_until(model, lambda m: not m.busy)
    model.tick()
    assert model.pending == 0
    assert model.target_status == 1
    assert len(model.targets) == 4


def test_queued_commands_expire_after_max_wait() -> None:
    model = navigating(busy_max_wait=5.0)
    model.set_busy(6.0)
    model.submit(c.Goto(0))
    run(model, 7.0)
    assert model.pending == 0
    assert model.commands_dropped == 1
    assert model.target_status == -1


# ---------------------------------------------------------------- faults, determinism
@pytest.mark.parametrize("firmware", FIRMWARES)
def test_planner_abort_next_goal(firmware: str) -> None:
    model = navigating(firmware)
    model.abort_next_goal()
    model.submit(c.Goto(1))
    run_until(model, lambda m: m.target_status == 0)
    s = status(model)
    assert s.target_distance == pytest.approx(1.5, abs=0.1)
    assert not arrived(s)
    model.submit(c.Goto(1))  # only the next goal was aborted
    run_until(model, lambda m: m.target_status == 0)
    assert arrived(status(model))


def test_planner_abort_probability_and_url_next() -> None:
    model = navigating(planner_abort=1.0)
    model.submit(c.Goto(0))
    run_until(model, lambda m: m.target_status == 0)
    assert model.target_distance > 0.5
    model = RobotModel(parse_sim_url("sim://?planner_abort=next&targets=2,0"))
    model.submit(c.StartNavigation())
    run_until(model, lambda m: m.visual_initialised and not m.busy)
    model.submit(c.Goto(0))
    run_until(model, lambda m: m.target_status == 0)
    assert model.target_distance == pytest.approx(1.0, abs=0.1)


def _trace(seed: int) -> list[tuple[Any, ...]]:
    model = navigating(seed=seed, planner_abort=0.5)
    out = []
    for target_id in (0, 1, 2, 0, 1, 2):
        model.submit(c.Goto(target_id))
        run_until(model, lambda m: m.target_status == 0)
        out.append(model.wire_values())
    return out


def test_deterministic_given_seed() -> None:
    assert _trace(3) == _trace(3)
    traces = {tuple(_trace(seed)) for seed in range(6)}
    assert len(traces) > 1  # the seed changes which goals abort


# ---------------------------------------------------------------- configuration
def test_url_parsing() -> None:
    config = parse_sim_url(
        "sim://?speed=20&layout=v1&firmware=document&seed=1&targets=1,2;3.5,-4"
        "&drop=0.1&garbage=0.2&bitflip=0.01&disconnect_after=5&concat_loss=false"
    )
    assert config.speed == 20
    assert config.layout is StatusLayout.V1
    assert config.firmware == "document"
    assert config.seed == 1
    assert config.targets == ((1.0, 2.0), (3.5, -4.0))
    assert (config.faults.drop, config.faults.garbage, config.faults.bitflip) == (0.1, 0.2, 0.01)
    assert config.faults.disconnect_after == 5.0
    assert config.effective_concat_loss is False
    assert parse_sim_url("sim://") == SimConfig()
    assert SimConfig().effective_concat_loss
    assert not SimConfig(firmware="document").effective_concat_loss
    assert SimConfig().effective_start_ignore_time == 10.0
    assert SimConfig(firmware="document").effective_start_ignore_time == 0.0


@pytest.mark.parametrize(
    "url",
    [
        "sim://?layout=v9",
        "sim://?layout=ros",
        "sim://?firmware=fake",
        "sim://?speed=0",
        "sim://?speed=fast",
        "sim://?drop=2",
        "sim://?bogus=1",
        "sim://?targets=1,2,3",
        "sim://?planner_abort=later",
        "sim://?concat_loss=maybe",
        "socket://?speed=2",
    ],
)
def test_bad_urls_raise_invalid_argument(url: str) -> None:
    with pytest.raises(InvalidArgument):
        parse_sim_url(url)


def test_lands_within_arrival_distance_even_facing_away() -> None:
    model = navigating(targets=((-0.004, 0.0), (-0.5, 0.0)), arrival_distance=0.005)
    model.submit(c.Goto(0))
    model.tick()
    assert (model.x, model.y) == (-0.004, 0.0)
    # Landed at once, but the goal shows as working in one frame before it ends.
    assert (model.target_status, model.target_distance) == (1, 0.0)
    model.tick()
    assert (model.target_status, model.target_distance) == (0, 0.0)
    model.submit(c.Goto(1))  # behind the robot: turns in place first, then drives
    model.tick()
    assert model.current_v == 0.0
    assert model.current_w != 0.0
    run_until(model, lambda m: m.target_status == 0)
    assert (model.x, model.y) == (-0.5, 0.0)


# ---------------------------------------------------------------- properties
_FIXED_COMMANDS = [
    c.StartNavigation(), c.StopNavigation(), c.Pause(), c.Resume(), c.Cancel(),
    c.ResetTargets(), c.StartPatrol(), c.StopPatrol(), c.StartMapping(), c.StopMapping(),
    c.SaveMap(), c.UpdateMap(), c.StartCharging(), c.StopCharging(), c.SaveDock(), c.Stop(),
]  # fmt: skip
_COMMANDS = st.one_of(
    st.sampled_from(_FIXED_COMMANDS),
    st.builds(c.Goto, st.integers(0, 12)),
    st.builds(c.Forward, st.integers(0, 100)),
    st.builds(c.Backward, st.integers(0, 100)),
    st.builds(c.TurnLeft, st.integers(0, 100)),
    st.builds(c.TurnRight, st.integers(0, 100)),
    st.builds(c.RotateTo, st.integers(-180, 180)),
    st.builds(c.SetPatrolDwell, st.integers(0, 5)),
    st.builds(c.AddTarget, st.floats(-20, 20), st.floats(-20, 20)),
)


@settings(max_examples=60)
@given(
    firmware=st.sampled_from(FIRMWARES),
    script=st.lists(st.tuples(_COMMANDS, st.integers(0, 90)), max_size=25),
)
def test_any_command_sequence_keeps_the_status_sane(
    firmware: str, script: list[tuple[c.Command, int]]
) -> None:
    model = make(firmware, visual_init_time=0.5, busy_on_start=0.2)
    encoder = FrameEncoder(StatusLayout.V2)
    decoder = StatusDecoder(StatusLayout.V2)
    for command, frames in script:
        model.submit(command)
        for _ in range(frames):
            model.tick()
            assert abs(model.current_v) <= 0.8 + 1e-9
            assert abs(model.current_w) <= 1.5 + 1e-9
            assert model.target_status in (-1, 0, 1, 2, 3)
            assert model.charge_status in (0, 1, 2, 3, 4)
            frame = encoder.encode(model.wire_values(), model.time_stamp)
            (decoded,) = decoder.feed(frame)
            expected = model.status()
            assert decoded.time_stamp == expected.time_stamp
            assert decoded.target_status == expected.target_status
            assert decoded.target_num_id == expected.target_num_id
            assert decoded.nav_status == expected.nav_status
            assert decoded.current_pose_x == pytest.approx(expected.current_pose_x, abs=1e-5)
    assert decoder.stats.lost_frames == 0
    assert decoder.stats.bytes_discarded == 0


def test_public_names_are_pinned() -> None:
    import galileo_async.sim
    import galileo_async.sim.memory

    assert sorted(galileo_async.sim.__all__) == sorted(
        [
            "DEFAULT_TARGETS", "FRAME_RATE", "SETTABLE_FIELDS", "Connector", "DeviceStats",
            "Faults", "FrameEncoder", "RobotModel", "SimConfig", "SimState", "Simulator", "Ticker",
            "parse_sim_url",
        ]
    )  # fmt: skip
    assert galileo_async.sim.memory.__all__ == ["MemoryTransport", "create_transport_pair"]


# --- goal faults: a dead navigation stack, a blocked robot (Faults.freeze_after, block_after)


def test_freeze_after_resends_the_status_of_that_moment_with_a_live_counter() -> None:
    model = navigating(freeze_after=1.0)
    model.submit(c.Goto(1))
    run(model, 1.5)
    frozen = model.status()
    assert frozen.target_status == 1
    assert frozen.target_distance > 0.5
    model.submit(c.Cancel())  # the dead stack executes nothing
    run(model, 10)
    later = model.status()
    assert later.time_stamp == frozen.time_stamp + 10 * FRAME_RATE
    assert later.model_copy(update={"time_stamp": frozen.time_stamp}) == frozen


def test_block_after_keeps_the_goal_working_with_the_robot_standing() -> None:
    model = navigating(block_after=1.0)
    model.submit(c.Goto(1))
    run(model, 1.5)
    blocked = model.status()
    run(model, 10)
    assert model.status().target_status == 1
    assert (model.x, model.y, model.target_distance) == (
        blocked.current_pose_x,
        blocked.current_pose_y,
        blocked.target_distance,
    )
    assert model.current_v == 0.0
    model.submit(c.Cancel())
    run(model, 0.1)
    assert model.status().target_status == 0


def test_goal_faults_come_from_the_url() -> None:
    faults = parse_sim_url("sim://?freeze_after=1&block_after=2.5").faults
    assert (faults.freeze_after, faults.block_after) == (1.0, 2.5)


@pytest.mark.parametrize("name", ["freeze_after", "block_after"])
def test_goal_faults_are_checked(name: str) -> None:
    with pytest.raises(InvalidArgument, match=name):
        parse_sim_url(f"sim://?{name}=-1")
