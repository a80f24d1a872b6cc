"""SimulatedDevice's scripting calls, each shown by its effect on the Robot (issue #26)."""

from __future__ import annotations

import asyncio
import math
import time
from collections.abc import AsyncIterator
from typing import Any

import pytest

from galileo_async import LinkState, NavStatus, Robot, TargetStatus, VisualStatus
from galileo_async.errors import (
    AcceptTimeout,
    ConnectionLost,
    GalileoError,
    GalileoTimeout,
    GoalAborted,
    GoalRejected,
    GoalStalled,
    InvalidArgument,
    LinkStale,
    NotReady,
    OperationTimeout,
)
from galileo_async.events import (
    ChargeStateChanged,
    ConnectionLostEvent,
    ConnectionRestored,
    Event,
    GoalAbortedEvent,
    GoalAccepted,
    GoalRejectedEvent,
    GoalStalledEvent,
    VisualLost,
    VisualRecovered,
)
from galileo_async.protocol import commands as c
from galileo_async.robot.runtime import OPEN_ROBOTS
from galileo_async.testing import ReceivedCommand, SimulatedDevice, VirtualClock, simulated_robot
from tests.support.cancel_ways import WAYS, stop_waiting

#: Seconds between two status frames of the simulated robot (30 Hz).
FRAME = 1 / 30
#: Virtual seconds any single wait of these tests may take before it fails.
WAIT = 120.0
#: A map with a target 100 m away (1) and one a 60 s trip away (2), from the start (0, 0).
FAR_MAP = ((0.0, 0.0), (100.0, 0.0), (46.0, 0.0))


@pytest.fixture
async def sim(request: pytest.FixtureRequest) -> AsyncIterator[tuple[Robot, SimulatedDevice]]:
    """simulated_robot(**kwargs): the test's indirect parameter, or none (a virtual clock)."""
    kwargs: dict[str, Any] = getattr(request, "param", {})
    async with simulated_robot(**kwargs) as pair:
        yield pair


def recorded(robot: Robot) -> list[Event]:
    """Every event of ``robot`` from now on, in order (a synchronous listener)."""
    events: list[Event] = []
    robot.add_event_listener(events.append)
    return events


def kinds(events: list[Event]) -> list[str]:
    """The events' names, in order."""
    return [event.name for event in events]


async def next_event(stream: AsyncIterator[Event], kind: type[Event]) -> Event:
    """The next ``kind`` on an events() stream, within WAIT virtual seconds."""
    async with asyncio.timeout(WAIT):
        async for event in stream:
            if isinstance(event, kind):
                return event
    raise AssertionError(f"the event stream ended before a {kind.__name__}")


@pytest.fixture
async def no_leftovers() -> AsyncIterator[None]:
    """The test ends with no Robot of its own open and the real clock back."""
    before = set(OPEN_ROBOTS)
    yield
    assert set(OPEN_ROBOTS) <= before
    assert VirtualClock.of() is None


# ----------------------------------------------------------------------- reject_next_goal


async def test_reject_next_goal_real_firmware_rejects_one_goal_with_minus_one(
    sim: tuple[Robot, SimulatedDevice],
) -> None:
    robot, device = sim
    await robot.goto(0)  # a goal ended: target_status 0, so the -1 of a refusal shows
    events = recorded(robot)
    device.reject_next_goal()
    with pytest.raises(GoalRejected) as info:
        await robot.goto(1)
    assert info.value.target_id == 1
    assert info.value.status is not None
    assert info.value.status.target_status == TargetStatus.INVALID
    assert kinds(events) == ["GoalRejected"]
    assert isinstance(events[0], GoalRejectedEvent)
    assert events[0].target_id == 1
    result = await robot.goto(1)  # the next goal only
    assert result.target_id == 1
    assert result.distance == pytest.approx(0.0, abs=0.3)
    assert device.received(c.Goto) == [c.Goto(0), c.Goto(1), c.Goto(1)]


async def test_reject_next_goal_on_a_navigating_robot_shows_at_once(
    sim: tuple[Robot, SimulatedDevice],
) -> None:
    robot, device = sim
    assert robot.status is not None
    assert robot.status.target_status == TargetStatus.FREE  # a robot in service
    device.reject_next_goal()
    with pytest.raises(GoalRejected):
        await robot.goto(1)
    assert device.received(c.Goto) == [c.Goto(1)]


@pytest.mark.parametrize("sim", [{"navigating": False}], indirect=True)
async def test_reject_next_goal_on_a_robot_just_started_is_unseen(
    sim: tuple[Robot, SimulatedDevice],
) -> None:
    robot, device = sim
    await robot.start_navigation()
    assert robot.status is not None
    assert robot.status.target_status == TargetStatus.INVALID  # no goal yet: -1 already
    device.clear()
    device.reject_next_goal()
    with pytest.raises(AcceptTimeout, match="rejected the id without a visible change"):
        await robot.goto(1, accept_timeout=2.0)
    assert device.received(c.Goto) == [c.Goto(1)]


@pytest.mark.parametrize("sim", [{"firmware": "document"}], indirect=True)
async def test_reject_next_goal_document_firmware_shows_error_three(
    sim: tuple[Robot, SimulatedDevice],
) -> None:
    robot, device = sim
    device.reject_next_goal()
    with pytest.raises(GoalRejected) as info:
        await robot.goto(2)
    assert info.value.status is not None
    assert info.value.status.target_status == TargetStatus.ERROR
    assert info.value.status.target_num_id == 2
    assert (await robot.goto(2)).target_id == 2


# ----------------------------------------------------------------------- abort_next_goal


async def test_abort_next_goal_stops_half_way_free(sim: tuple[Robot, SimulatedDevice]) -> None:
    robot, device = sim
    events = recorded(robot)
    device.abort_next_goal()
    with pytest.raises(GoalAborted) as info:
        await robot.goto(2)  # (0, 5): 5 m away
    assert info.value.target_id == 2
    assert info.value.distance == pytest.approx(2.5, abs=0.3)
    assert robot.status is not None
    assert robot.status.target_status == TargetStatus.FREE
    assert kinds(events) == ["GoalAccepted", "GoalAborted"]
    assert isinstance(events[-1], GoalAbortedEvent)
    assert (await robot.goto(2)).distance == pytest.approx(0.0, abs=0.3)  # the next one arrives


# ----------------------------------------------------------------------- busy


async def test_a_goto_waits_out_busy_before_sending(sim: tuple[Robot, SimulatedDevice]) -> None:
    robot, device = sim
    events = recorded(robot)
    busy_from = device.time
    device.busy(3.0)
    await device.advance(0.1)
    assert robot.status is not None
    assert robot.status.busy_status == 1
    goal = asyncio.create_task(robot.goto(0))
    await device.advance(2.5)
    assert device.received() == []  # the driver holds the goal while the robot is busy
    assert not goal.done()
    result = await goal
    assert result.target_id == 0
    [sent] = device.commands
    assert sent.command == c.Goto(0)
    assert not sent.busy
    assert sent.at >= busy_from + 3.0 - 1e-9
    assert kinds(events)[:3] == ["BusyStarted", "BusyEnded", "GoalAccepted"]


async def test_a_command_the_busy_robot_receives_waits_until_busy_ends(
    sim: tuple[Robot, SimulatedDevice],
) -> None:
    robot, device = sim
    events = recorded(robot)
    device.busy(60.0)  # the Robot has not seen it yet: it sends at once
    goal = asyncio.create_task(robot.goto(0))
    await device.advance(1.0)
    [sent] = device.commands
    assert sent == ReceivedCommand(sent.at, c.Goto(0), busy=True)
    assert robot.status is not None
    assert robot.status.busy_status == 1
    assert device.state.pending_commands == 1  # queued, not started
    assert robot.status.target_status != TargetStatus.WORKING
    assert "GoalAccepted" not in kinds(events)
    ended_at_frame = device.state.time_stamp
    device.busy(0)  # busy ends now: the queued goal starts
    result = await goal
    assert result.target_id == 0
    accepted = events[kinds(events).index("GoalAccepted")]
    assert accepted.status is not None
    assert accepted.status.time_stamp == ended_at_frame + 1  # the very next frame
    assert accepted.status.busy_status == 0


# ----------------------------------------------------------------------- lose_visual


async def test_lose_visual_halts_the_robot_and_keeps_the_goal_until_tracking_is_set(
    sim: tuple[Robot, SimulatedDevice],
) -> None:
    robot, device = sim
    stream = robot.events()
    goal = asyncio.create_task(robot.goto(0))  # (2, 0) straight ahead
    await next_event(stream, GoalAccepted)
    await device.advance(1.0)
    device.lose_visual()
    await next_event(stream, VisualLost)
    halted = device.pose
    await device.advance(30.0)
    assert device.pose == halted  # the robot stands still
    status = robot.status
    assert status is not None
    assert status.visual_status == VisualStatus.LOST
    assert status.current_speed_x == 0.0
    assert status.target_status == TargetStatus.WORKING  # the goal stays working
    assert not goal.done()
    device.set(visual_status=1)
    await next_event(stream, VisualRecovered)
    result = await goal
    assert result.distance == pytest.approx(0.0, abs=0.3)


async def test_lose_visual_for_seconds_recovers_by_itself(
    sim: tuple[Robot, SimulatedDevice],
) -> None:
    robot, device = sim
    events = recorded(robot)
    goal = asyncio.create_task(robot.goto(0))
    await device.advance(1.0)
    device.lose_visual(5.0)
    await device.advance(4.9)
    assert robot.status is not None
    assert robot.status.visual_status == VisualStatus.LOST
    await device.advance(0.2)
    assert robot.status is not None
    assert robot.status.visual_status == VisualStatus.TRACKING
    assert (await goal).target_id == 0
    assert kinds(events) == ["GoalAccepted", "VisualLost", "VisualRecovered", "GoalReached"]


# ----------------------------------------------------------------------- freeze / thaw


async def test_freeze_stalls_a_goal_after_progress_timeout(
    sim: tuple[Robot, SimulatedDevice],
) -> None:
    robot, device = sim
    events = recorded(robot)
    goal = asyncio.create_task(robot.goto(1, progress_timeout=10.0))  # (4, 3): 5 m
    await device.advance(3.0)
    device.freeze()
    await device.advance(0.1)
    frozen = robot.status
    assert frozen is not None
    await device.advance(5.0)
    status = robot.status
    assert status is not None
    assert status.time_stamp > frozen.time_stamp  # a live counter on a dead status
    assert status.model_dump(exclude={"time_stamp"}) == frozen.model_dump(exclude={"time_stamp"})
    assert robot.link_state is LinkState.UP
    assert not goal.done()
    with pytest.raises(GoalStalled) as info:
        await goal
    assert info.value.stalled_for == 10.0
    assert isinstance(events[-1], GoalStalledEvent)
    assert events[-1].target_id == 1
    assert device.received()[-1] == c.Cancel()  # sent before the error was raised


async def test_thaw_lets_the_frozen_goal_proceed(sim: tuple[Robot, SimulatedDevice]) -> None:
    robot, device = sim
    goal = asyncio.create_task(robot.goto(1, progress_timeout=10.0))
    await device.advance(3.0)
    device.freeze()
    stopped = device.status
    await device.advance(8.0)
    assert device.status.model_dump(exclude={"time_stamp"}) == stopped.model_dump(
        exclude={"time_stamp"}
    )
    device.thaw()
    result = await goal
    assert result.target_id == 1
    assert result.distance == pytest.approx(0.0, abs=0.3)


# ----------------------------------------------------------------------- drop / restore link


async def test_drop_link_loses_the_link_until_restore_link(
    sim: tuple[Robot, SimulatedDevice],
) -> None:
    robot, device = sim
    stream = robot.events()
    goal = asyncio.create_task(robot.goto(1))
    await next_event(stream, GoalAccepted)
    device.drop_link()
    with pytest.raises(ConnectionLost):  # the goal in flight fails at once
        await goal
    assert robot.link_state is LinkState.LOST
    await next_event(stream, ConnectionLostEvent)
    await device.advance(30.0)  # the driver retries; every retry is refused
    assert robot.link_state is LinkState.LOST
    assert device.state.connections == 0
    with pytest.raises(ConnectionLost, match="nothing was sent"):
        await robot.goto(0)
    assert device.received() == [c.Goto(1)]
    device.restore_link()
    assert await robot.wait_link(LinkState.UP, timeout=30.0) is LinkState.UP
    await next_event(stream, ConnectionRestored)
    assert device.state.connections == 1
    assert (await robot.goto(0)).target_id == 0  # works again


# ----------------------------------------------------------------------- place / set


async def test_place_puts_the_robot_where_its_status_shows_it(
    sim: tuple[Robot, SimulatedDevice],
) -> None:
    robot, device = sim
    device.place(1.5, -2.0, math.pi / 2)
    status = await robot.wait_until(
        lambda s: s.current_pose_x == pytest.approx(1.5, abs=1e-3), timeout=1.0
    )
    assert status.current_pose_y == pytest.approx(-2.0, abs=1e-3)
    assert status.current_angle == pytest.approx(math.pi / 2, abs=1e-3)
    assert device.pose.x == 1.5
    assert device.pose.y == -2.0
    with pytest.raises(InvalidArgument):
        device.place(math.nan, 0.0)
    with pytest.raises(InvalidArgument):
        device.place(0.0, 0.0, "north")  # type: ignore[arg-type]
    assert device.pose.x == 1.5
    assert device.pose.y == -2.0


async def test_set_overrides_status_fields_from_the_next_frame(
    sim: tuple[Robot, SimulatedDevice],
) -> None:
    robot, device = sim
    stream = robot.events()
    device.set(power=22.5, charge_status=1)
    event = await next_event(stream, ChargeStateChanged)
    assert isinstance(event, ChargeStateChanged)
    assert int(event.new) == 1
    assert robot.status is not None
    assert robot.status.power == pytest.approx(22.5, abs=0.01)
    device.set(nav_status=0)
    await robot.wait_until(lambda s: s.nav_status == NavStatus.CLOSED, timeout=1.0)
    with pytest.raises(NotReady):
        await robot.goto(0)
    assert device.received() == []


@pytest.mark.parametrize(
    "fields",
    [
        {"bogus": 1},
        {"power": 20.0, "busy_status": 1},  # not settable: follows from busy()
        {"power": math.nan},
        {"power": "20"},
        {"power": 20.0, "nav_status": 1.5},
        {"power": 20.0, "nav_status": True},
        {"power": 20.0, "target_num_id": 2**40},
    ],
)
async def test_set_rejects_bad_names_and_values_before_changing_anything(
    sim: tuple[Robot, SimulatedDevice], fields: dict[str, Any]
) -> None:
    robot, device = sim
    before = device.status
    with pytest.raises(InvalidArgument):
        device.set(**fields)
    await device.advance(0.5)
    after = robot.status
    assert after is not None
    assert after.power == pytest.approx(before.power, abs=0.01)
    assert after.nav_status == before.nav_status
    assert after.target_num_id == before.target_num_id


# ----------------------------------------------------------------------- the command log


async def test_the_command_log_keeps_order_and_simulated_time(
    sim: tuple[Robot, SimulatedDevice],
) -> None:
    robot, device = sim
    await device.advance(2.0)
    loop = asyncio.get_running_loop()
    first_at = loop.time()
    await robot.send(c.Goto(2))
    await device.advance(1.5)
    await robot.send(c.Pause())
    await robot.send(c.Resume())
    await device.advance(0.5)
    log = device.commands
    assert [r.command for r in log] == [c.Goto(2), c.Pause(), c.Resume()]
    assert all(isinstance(r, ReceivedCommand) and not r.busy for r in log)
    assert log[0].at == pytest.approx(2.0, abs=2 * FRAME)  # simulated seconds since start
    assert log[1].at - log[0].at == pytest.approx(1.5, abs=2 * FRAME)
    assert log[0].at <= log[1].at <= log[2].at <= device.time
    assert device.time - log[0].at == pytest.approx(loop.time() - first_at, abs=2 * FRAME)
    assert device.received(c.Pause, c.Resume) == [c.Pause(), c.Resume()]
    assert device.received(c.Cancel) == []
    log.clear()  # a copy: the device's log is untouched
    assert len(device.commands) == 3
    device.clear()
    assert device.commands == []
    assert device.received() == []
    await robot.send(c.Cancel())
    await device.advance(0.1)
    assert device.received() == [c.Cancel()]


# ----------------------------------------------------------------------- advance


@pytest.mark.parametrize("sim", [{"targets": FAR_MAP}], indirect=True)
async def test_advance_fires_a_goal_timeout_exactly_on_time(
    sim: tuple[Robot, SimulatedDevice],
) -> None:
    robot, device = sim
    loop = asyncio.get_running_loop()
    start = loop.time()
    ended: list[float] = []
    goal = asyncio.create_task(robot.goto(1, timeout=5.0))
    goal.add_done_callback(lambda _: ended.append(loop.time() - start))
    await device.advance(4.9)
    assert not goal.done()
    await device.advance(0.2)
    assert goal.done()
    with pytest.raises(OperationTimeout):
        await goal
    assert ended == [pytest.approx(5.0, abs=1e-6)]
    goto, cancel = device.commands
    assert cancel.command == c.Cancel()
    assert cancel.at - goto.at == pytest.approx(5.0, abs=FRAME)


@pytest.mark.parametrize("sim", [{"targets": FAR_MAP}], indirect=True)
async def test_advance_runs_a_sixty_second_trip(sim: tuple[Robot, SimulatedDevice]) -> None:
    robot, device = sim
    goal = asyncio.create_task(robot.goto(2))
    await device.advance(50.0)
    assert not goal.done()
    await device.advance(10.0)
    assert goal.done()
    result = goal.result()
    assert 55.0 < result.elapsed <= 60.0
    assert device.pose.x == pytest.approx(46.0, abs=0.01)


async def test_advance_rejects_what_is_not_seconds(sim: tuple[Robot, SimulatedDevice]) -> None:
    _, device = sim
    before = device.time
    for bad in (-1.0, math.nan, True):
        with pytest.raises(InvalidArgument):
            await device.advance(bad)
    assert device.time == before


# ----------------------------------------------------------------------- options


@pytest.mark.parametrize("sim", [{"navigating": False}], indirect=True)
async def test_not_navigating_needs_start_navigation(sim: tuple[Robot, SimulatedDevice]) -> None:
    robot, device = sim
    assert robot.status is not None
    assert robot.status.nav_status == NavStatus.CLOSED
    with pytest.raises(NotReady):
        await robot.goto(0)
    assert device.received() == []
    await robot.start_navigation()
    assert (await robot.goto(0)).target_id == 0
    assert device.received() == [c.StartNavigation(), c.Goto(0)]


@pytest.mark.parametrize("sim", [{"map_targets": 9}], indirect=True)
async def test_map_targets_sizes_the_map(sim: tuple[Robot, SimulatedDevice]) -> None:
    robot, device = sim
    assert robot.map_targets == 9
    assert len(device.state.targets) == 9
    assert (await robot.goto(8)).target_id == 8
    with pytest.raises(GoalRejected):
        await robot.goto(9)


@pytest.mark.parametrize("sim", [{"targets": [(1, 0), (0, 1)], "layout": "v1"}], indirect=True)
async def test_targets_and_layout_shape_the_robot(sim: tuple[Robot, SimulatedDevice]) -> None:
    robot, device = sim
    assert robot.map_targets == 2
    assert device.state.targets == ((1.0, 0.0), (0.0, 1.0))
    assert robot.status is not None
    assert robot.status.layout == "v1"
    assert (await robot.goto(1)).target_id == 1


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"map_targets": 3, "targets": [(0, 0), (1, 1)]}, "contradicts"),
        ({"map_targets": 256}, "map_targets"),
        ({"map_targets": True}, "map_targets"),
        ({"targets": [(1.0,)]}, "targets"),
        ({"targets": [("a", 0)]}, "targets"),
        ({"targets": [(math.inf, 0)]}, "targets"),
        ({"targets": 5}, "targets"),
        ({"sim_options": {"firmware": "document"}}, "firmware"),
        ({"sim_options": {"layout": "v1"}}, "layout"),
        ({"sim_options": {"targets": ()}}, "targets"),
        ({"sim_options": {"speed": 2.0}}, "speed"),
        ({"sim_options": {"no_such_option": 1}}, "no_such_option"),
        ({"sim_options": 5}, "sim_options"),
        ({"clock": "fast"}, "clock"),
        ({"navigating": 1}, "navigating"),
        ({"firmware": "beta"}, "firmware"),
        ({"layout": "v9"}, "layout"),
        ({"no_such_option": 1}, "no_such_option"),
        ({"accept_timeout": -1.0}, "accept_timeout"),
    ],
)
@pytest.mark.usefixtures("no_leftovers")
async def test_bad_arguments_raise_invalid_argument_and_leave_nothing(
    kwargs: dict[str, Any], message: str
) -> None:
    with pytest.raises(InvalidArgument, match=message):
        async with simulated_robot(**kwargs):
            raise AssertionError("started despite a bad argument")


@pytest.mark.usefixtures("no_leftovers")
async def test_an_empty_map_is_a_map_of_zero_targets() -> None:
    for kwargs in ({"targets": []}, {"map_targets": 0}):
        async with simulated_robot(**kwargs) as (robot, device):
            assert robot.map_targets == 0
            assert device.state.targets == ()


# ----------------------------------------------------------------------- the real clock


@pytest.mark.parametrize("sim", [{"clock": "real", "sim_options": {"speed": 20.0}}], indirect=True)
async def test_the_real_clock_has_no_advance_and_the_robot_still_works(
    sim: tuple[Robot, SimulatedDevice],
) -> None:
    robot, device = sim
    loop = asyncio.get_running_loop()
    assert VirtualClock.of() is None
    real_start = time.monotonic()
    loop_start = loop.time()
    await asyncio.sleep(0.01)  # a real wait on the real clock
    loop_elapsed = loop.time() - loop_start
    assert 0.009 <= loop_elapsed <= time.monotonic() - real_start
    with pytest.raises(GalileoError, match="clock='virtual'"):
        await device.advance(1.0)
    async with asyncio.timeout(10):  # real seconds: ~0.15 at 20 x
        result = await robot.goto(0)
    assert result.distance == pytest.approx(0.0, abs=0.3)
    assert device.received() == [c.Goto(0)]


# ----------------------------------------------------------------------- next_command


async def test_next_command_is_the_next_of_its_kind_with_its_time(
    sim: tuple[Robot, SimulatedDevice],
) -> None:
    robot, device = sim
    await device.advance(1.0)
    waiting = asyncio.create_task(device.next_command(c.Goto))
    await robot.cancel()  # a Cancel arrives first: not a Goto
    goal = asyncio.create_task(robot.goto(1))
    received = await waiting
    assert received.command == c.Goto(1)
    assert received.at == pytest.approx(device.time, abs=2 * FRAME)
    assert received.at > 1.0
    assert device.received() == [c.Cancel(), c.Goto(1)]
    await goal


async def test_next_command_without_kinds_takes_any(sim: tuple[Robot, SimulatedDevice]) -> None:
    robot, device = sim
    waiting = asyncio.create_task(device.next_command())
    await robot.cancel()
    assert (await waiting).command == c.Cancel()


async def test_next_command_times_out_on_the_loop_clock(
    sim: tuple[Robot, SimulatedDevice],
) -> None:
    _, device = sim
    loop = asyncio.get_running_loop()
    began = loop.time()
    with pytest.raises(GalileoTimeout, match="no Goto arrived within 5"):
        await device.next_command(c.Goto, timeout=5)
    assert loop.time() - began == pytest.approx(5.0, abs=1e-6)
    assert device._waiters == []  # nothing left to resolve


@pytest.mark.parametrize("how", WAYS)
async def test_next_command_cancelled_every_way_leaves_no_waiter(
    sim: tuple[Robot, SimulatedDevice], how: str
) -> None:
    _, device = sim
    await stop_waiting(how, lambda: device.next_command(c.Goto), after=2.0)
    assert device._waiters == []


@pytest.mark.parametrize("bad", [0, -1, math.nan, True, "1"])
async def test_next_command_checks_its_timeout(
    sim: tuple[Robot, SimulatedDevice], bad: object
) -> None:
    _, device = sim
    with pytest.raises(InvalidArgument):
        await device.next_command(timeout=bad)  # type: ignore[arg-type]
    assert device._waiters == []


# ----------------------------------------------------------------------- mute


@pytest.mark.parametrize("sim", [{"stale_timeout": 0.5}], indirect=True)
async def test_mute_turns_the_link_stale_and_unmute_fresh(
    sim: tuple[Robot, SimulatedDevice],
) -> None:
    robot, device = sim
    events = recorded(robot)
    loop = asyncio.get_running_loop()
    await robot.wait_until(lambda s: True)
    heard = robot.link.last_frame_at
    assert heard is not None
    device.mute()
    stale = await robot.wait_link(LinkState.STALE, timeout=WAIT)
    assert stale is LinkState.STALE
    # Stale exactly stale_timeout after the last frame.
    assert loop.time() - heard == pytest.approx(0.5, abs=1e-6)
    assert kinds(events) == ["LinkStale"]  # once, however long the silence
    with pytest.raises(LinkStale, match="cancel: sent"):
        await robot.cancel()  # sent and received; only its confirmation cannot come
    assert device.received() == [c.Cancel()]
    device.unmute()
    await robot.wait_link(LinkState.UP, timeout=WAIT)
    assert kinds(events)[-1] == "LinkRestored"
