"""Visualization: one clock per event loop, an unchanged one repeated once a second only."""

from __future__ import annotations

import asyncio
from collections import Counter
from typing import Any

import anyio
import pytest

import galileo_async as galileo
from galileo_async.models import GalileoStatus, NavStatus, VisualStatus
from galileo_async.robot import Robot
from galileo_async.testing import VirtualClock
from galileo_async.vda5050 import Vehicle, VehicleConfig, report
from galileo_async.vda5050.models import BaseModel, Visualization
from galileo_async.vda5050.visualization import KEEP_ALIVE, TICK, VisualizationClock, clock
from tests.support.vda5050_support import Broker, broker_fixture  # noqa: F401 (fixture)
from tests.vda5050.test_vda5050_vehicle import FAST_SIM


async def test_one_timer_serves_every_vehicle_at_its_rate() -> None:
    loop = asyncio.get_running_loop()
    virtual = VirtualClock.install(loop)
    try:
        ticks = VisualizationClock(loop)
        calls: Counter[int] = Counter()
        timers = 0
        call_at = loop.call_at

        def counted(when: float, callback: Any, *args: Any, **options: Any) -> asyncio.TimerHandle:
            nonlocal timers
            if getattr(callback, "__self__", None) is ticks:
                timers += 1
            return call_at(when, callback, *args, **options)

        loop.call_at = counted  # type: ignore[method-assign]
        try:
            for key in range(200):
                ticks.add(key, 0.1, lambda now, key=key: calls.update([key]), key / 200)
            await asyncio.sleep(1.0)
        finally:
            del loop.call_at  # the loop's own again
            for key in range(200):
                ticks.remove(key)
        assert all(9 <= calls[key] <= 11 for key in range(200)), calls
        # 2000 visualizations from at most one wake-up a tick, not a timer each.
        assert timers <= 1.0 / TICK + 2, timers
        assert not ticks.running
        assert len(ticks) == 0
    finally:
        virtual.release()


async def test_a_callback_that_raises_keeps_its_turn() -> None:
    loop = asyncio.get_running_loop()
    virtual = VirtualClock.install(loop)
    try:
        ticks = VisualizationClock(loop)
        calls: list[float] = []

        def fails(now: float) -> None:
            calls.append(now)
            raise RuntimeError("boom")

        ticks.add("k", 0.1, fails, 0.0)
        await asyncio.sleep(0.55)
        ticks.remove("k")
        assert len(calls) == 6
        assert not ticks.running
    finally:
        virtual.release()


class _Session:
    """Stands in for the vehicle's MQTT session: connected, records what is published."""

    def __init__(self) -> None:
        self.connected = True
        self.published: list[dict[str, Any]] = []

    def publish_now(self, topic: str, message: BaseModel) -> bool:
        assert topic == "visualization"
        self.published.append(message.model_dump(exclude_none=True))
        return True


def _status(x: float, speed: float = 0.0) -> GalileoStatus:
    return GalileoStatus(
        nav_status=NavStatus.OPEN, visual_status=VisualStatus.TRACKING, power=25.0,
        current_pose_x=x, current_pose_y=2.0, current_angle=0.5, current_speed_x=speed,
        current_speed_theta=0.0,
    )  # fmt: skip


async def test_an_unchanged_visualization_goes_out_once_a_second(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    current = [_status(1.0)]
    monkeypatch.setattr(Robot, "status", property(lambda robot: current[0]))
    config = VehicleConfig(broker="mqtt://127.0.0.1", manufacturer="m", serial_number="s")
    async with galileo.connect("sim://") as robot:
        vehicle = Vehicle(robot, config)  # not run: the clock's calls are made by hand
        session = _Session()
        vehicle.session = session  # type: ignore[assignment]
        for tick in range(10):
            vehicle._visualize(100.0 + tick / 10)
        assert len(session.published) == 1  # the same position and velocity: once
        vehicle._visualize(100.0 + KEEP_ALIVE)
        assert len(session.published) == 2  # the keep-alive
        current[0] = _status(1.5, speed=0.2)
        vehicle._visualize(101.1)
        assert len(session.published) == 3  # moved: at once
        assert session.published[-1]["agvPosition"]["x"] == 1.5
        assert session.published[-1]["velocity"]["vx"] == 0.2
        vehicle._visualize(101.2)
        assert len(session.published) == 3
        assert [m["headerId"] for m in session.published] == [0, 1, 2]
        session.connected = False
        vehicle._visualize(101.3)
        session.connected = True
        vehicle._visualize(101.4)
        assert len(session.published) == 4  # the first after a reconnect goes out


async def test_vehicles_on_one_loop_share_one_clock(broker: Broker) -> None:
    count = 5
    async with galileo.connect(FAST_SIM) as robot, anyio.create_task_group() as group:
        vehicles = [
            Vehicle(robot, VehicleConfig(broker=broker.url, manufacturer="acme",
                                         serial_number=f"r{n}"))
            for n in range(count)
        ]  # fmt: skip
        for vehicle in vehicles:
            group.start_soon(vehicle.run)
        with anyio.fail_after(20):
            for vehicle in vehicles:
                await vehicle.wait_online()
        shared = clock()
        assert len(shared) == count
        assert shared.running
        group.cancel_scope.cancel()
    assert len(shared) == 0  # nothing left on the loop
    assert not shared.running


class _Json:
    """Stands in for the session: records each message's JSON as published."""

    connected = True

    def __init__(self) -> None:
        self.published: list[str] = []

    def publish_now(self, topic: str, message: BaseModel) -> bool:
        self.published.append(message.model_dump_json(exclude_none=True))
        return True


@pytest.mark.parametrize(
    "fields",
    [
        {},
        {"current_pose_x": 1.23456, "current_pose_y": -2.0, "current_angle": 7.0,
         "current_speed_x": 0.123456, "current_speed_theta": -0.5},
        {"current_pose_x": -1.0, "current_pose_y": -1.0, "current_angle": -1.0,
         "current_speed_x": 0.0},
        {"current_pose_x": 0.1, "current_pose_y": 0.2, "current_angle": -3.5,
         "visual_status": VisualStatus.LOST, "current_speed_theta": 0.3},
        {"current_pose_x": 3.0, "current_pose_y": 4.0, "current_angle": 0.0,
         "nav_status": NavStatus.CLOSED, "current_speed_x": -0.25},
        None,
    ],
    ids=["nothing", "driving", "unknown pose", "tracking lost", "navigation closed", "no status"],
)  # fmt: skip
async def test_a_visualization_is_the_message_of_its_state_parts(
    monkeypatch: pytest.MonkeyPatch, fields: dict[str, Any] | None
) -> None:
    """Byte for byte what report.agv_position and report.velocity make of the status."""
    base = {"nav_status": NavStatus.OPEN, "visual_status": VisualStatus.TRACKING}
    status = None if fields is None else GalileoStatus(**{**base, **fields})
    monkeypatch.setattr(Robot, "status", property(lambda robot: status))
    config = VehicleConfig(broker="mqtt://127.0.0.1", manufacturer="m", serial_number="s",
                           map_id="hall")  # fmt: skip
    async with galileo.connect("sim://") as robot:
        vehicle = Vehicle(robot, config)
        session = _Json()
        vehicle.session = session  # type: ignore[assignment]
        vehicle._visualize(100.0)
    [published] = session.published
    sent = Visualization.model_validate_json(published)
    expected = Visualization(
        headerId=0, timestamp=sent.timestamp, version="2.0.0", manufacturer="m",
        serialNumber="s", agvPosition=report.agv_position(status, "hall"),
        velocity=report.velocity(status),
    )  # fmt: skip
    assert published == expected.model_dump_json(exclude_none=True)
