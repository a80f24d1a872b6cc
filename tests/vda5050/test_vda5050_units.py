"""Pure parts of the VDA 5050 vehicle: broker URLs, config, order rules, the state report."""

from __future__ import annotations

from typing import Any

import pytest

from galileo_async.battery import battery_charge
from galileo_async.errors import InvalidArgument
from galileo_async.models import ChargeStatus, GalileoStatus, NavStatus, VisualStatus
from galileo_async.vda5050 import (
    OrderProgress,
    Rejection,
    VehicleConfig,
    check_order,
    parse_broker_url,
    report,
)
from galileo_async.vda5050.models import Order
from tests.support.vda5050_support import VALIDATORS, make_order, node


def order(order_id: str, nodes: list[dict[str, Any]], update: int = 0, seq: int = 0) -> Order:
    header = {"headerId": 1, "timestamp": "2026-01-01T00:00:00.000Z", "version": "2.0.0",
              "manufacturer": "acme", "serialNumber": "r1"}  # fmt: skip
    return Order.model_validate({**header, **make_order(order_id, nodes, update, seq)})


@pytest.mark.parametrize(
    ("url", "expected"),
    [
        ("mqtt://127.0.0.1", ("127.0.0.1", 1883, False, None, None)),
        ("mqtts://broker:9000", ("broker", 9000, True, None, None)),
        ("mqtt://me:p%40ss@[::1]:1884", ("::1", 1884, False, "me", "p@ss")),
        ("mqtts://me@host/", ("host", 8883, True, "me", None)),
    ],
)
def test_broker_urls(url: str, expected: tuple[object, ...]) -> None:
    address = parse_broker_url(url)
    password = None if address.password is None else address.password.get_secret_value()
    assert (address.host, address.port, address.tls, address.username, password) == expected


@pytest.mark.parametrize(
    "url", ["", "tcp://host", "mqtt://", "mqtt://host:99999", "mqtt://host/path", "mqtt://h?x=1"]
)
def test_bad_broker_urls(url: str) -> None:
    with pytest.raises(InvalidArgument):
        parse_broker_url(url)


@pytest.mark.parametrize(
    "options",
    [
        {"manufacturer": "a/b"}, {"serial_number": ""}, {"interface_name": "u#"},
        {"visualization_rate": 31.0}, {"visualization_rate": -1.0}, {"state_interval": 0},
        {"broker_loss_stop_delay": float("nan")}, {"reconnect_max": 0.1}, {"keepalive": 0},
        {"map_id": ""}, {"broker": "http://x"},
    ],
)  # fmt: skip
def test_bad_config_is_refused_before_anything_opens(options: dict[str, Any]) -> None:
    base: dict[str, Any] = {"broker": "mqtt://127.0.0.1", "manufacturer": "m", "serial_number": "s"}
    with pytest.raises(InvalidArgument):
        VehicleConfig(**{**base, **options})


def test_topics_and_defaults() -> None:
    config = VehicleConfig(broker="mqtt://127.0.0.1", manufacturer="acme", serial_number="7")
    assert config.topic("state") == "uagv/v2/acme/7/state"
    assert config.visualization_rate == 10.0
    assert config.state_interval == 30.0
    assert VehicleConfig(broker="mqtt://h", manufacturer="m", serial_number="s",
                         visualization_rate=30.0).visualization_rate == 30.0  # fmt: skip


def test_check_order_names_what_is_wrong() -> None:
    with pytest.raises(Rejection) as caught:
        check_order(order("o", [node("a", 0, 0), node("x/y")]), map_id="map")
    assert caught.value.error.errorType == "orderError"
    refs = {(r.referenceKey, r.referenceValue) for r in caught.value.error.errorReferences}
    assert refs >= {("orderId", "o"), ("nodeId", "x/y")}
    check_order(order("o", [node("a", 0, 0), node("255")]), map_id="map")
    with pytest.raises(Rejection, match="map target"):
        check_order(order("o", [node("a", 0, 0), node("256")]), map_id="map")
    horizon_first = order("o", [node("a", 0, 0, released=False)])
    with pytest.raises(Rejection, match="first node must be released"):
        check_order(horizon_first, map_id="map")
    released_after_horizon = order(
        "o", [node("a", 0, 0), node("b", 1, 0, released=False), node("c", 2, 0)]
    )
    with pytest.raises(Rejection, match=r"released or not|follows the horizon"):
        check_order(released_after_horizon, map_id="map")
    with pytest.raises(Rejection, match="needs at least one node"):
        check_order(order("o", []), map_id="map")


def test_progress_new_order_resent_lower_and_stitch() -> None:
    progress = OrderProgress()
    first = order("o", [node("a", 0, 0), node("b", 1, 0), node("c", 2, 0, released=False)])
    assert progress.decide(first, (0.1, 0.0), 0.5) == "new"
    progress.accept(first, "new")
    assert (progress.last_node_id, progress.last_node_sequence_id) == ("a", 0)
    assert [n.nodeId for n in progress.nodes] == ["b", "c"]
    assert progress.decide(first, None, 0.5) == "ignore"
    step = progress.next_step()
    assert step is not None
    assert step[1].nodeId == "b"
    progress.reached(step[1])
    assert progress.next_step() is None
    assert progress.new_base_request
    update = order("o", [node("b", 1, 0), node("c", 2, 0), node("d", 3, 0)], update=1, seq=2)
    assert progress.decide(update, None, 0.5) == "stitch"
    progress.accept(update, "stitch")
    assert [(n.nodeId, n.released) for n in progress.nodes] == [("c", True), ("d", True)]
    assert [e.edgeId for e in progress.edges] == ["eb-c", "ec-d"]
    with pytest.raises(Rejection) as lower:
        progress.decide(order("o", [node("b", 1, 0)], update=0, seq=2), None, 0.5)
    assert lower.value.error.errorType == "orderUpdateError"
    other = order("p", [node("z", 9, 9)])
    with pytest.raises(Rejection, match="still running") as running:
        progress.decide(other, (2.0, 0.0), 0.5)
    assert running.value.error.errorType == "orderUpdateError"  # Figure 8, step 3
    progress.clear()
    with pytest.raises(Rejection, match="neither FINISHED nor FAILED") as acting:
        progress.decide(other, (9.0, 9.0), 0.5, actions_running=True)
    assert acting.value.error.errorType == "orderUpdateError"
    with pytest.raises(Rejection) as far:
        progress.decide(other, (2.0, 0.0), 0.5)
    assert far.value.error.errorType == "noRouteError"
    assert "the vehicle is at x 2.000 m, y 0.000 m; the nearest node is c" in str(far.value)
    with pytest.raises(Rejection) as placed:
        progress.decide(other, (8.0, 9.0), 0.5, theta=7.0, map_id="map")
    assert "x 8.000 m, y 9.000 m, theta 0.717 rad on map map" in str(placed.value)
    assert "the nearest node is z, 1.00 m away" in str(placed.value)
    with pytest.raises(Rejection, match="position is unknown"):
        progress.decide(other, None, 0.5)
    assert progress.decide(order("p", [node("b")]), None, 0.5) == "new"  # its last node


def status(**fields: Any) -> GalileoStatus:
    base: dict[str, Any] = {
        "nav_status": NavStatus.OPEN, "visual_status": VisualStatus.TRACKING,
        "charge_status": ChargeStatus.FREE, "power": 25.0, "current_pose_x": 1.0,
        "current_pose_y": 2.0, "current_angle": 4.0, "current_speed_x": 0.5,
        "current_speed_theta": 0.1,
    }  # fmt: skip
    return GalileoStatus(**{**base, **fields})


def test_battery_curve() -> None:
    assert battery_charge(21.0) == 0.0
    assert battery_charge(29.0) == 100.0
    assert battery_charge(25.0) == 45.0
    charges = [battery_charge(v / 10) for v in range(200, 300)]
    assert charges == sorted(charges)
    battery = report.battery_state(status(charge_status=ChargeStatus.CHARGING))
    assert battery.charging
    assert battery.batteryVoltage == 25.0


def test_status_report() -> None:
    position = report.agv_position(status(), "hall")
    assert position is not None
    assert (position.x, position.y, position.mapId, position.positionInitialized) == (
        1.0, 2.0, "hall", True
    )  # fmt: skip
    assert -3.1416 <= position.theta <= 3.1416  # 4 rad wraps to -2.28
    lost = status(visual_status=VisualStatus.LOST)
    assert not report.agv_position(lost, "m").positionInitialized  # type: ignore[union-attr]
    assert [e.errorType for e in report.status_errors(lost)] == ["visualLost"]
    assert report.operating_mode(status(nav_status=NavStatus.CLOSED)) == "MANUAL"
    assert report.driving(status())
    assert not report.driving(status(current_speed_x=0.0, current_speed_theta=0.0))
    assert report.agv_position(None, "m") is None
    assert report.velocity(None) is None


def test_factsheet_follows_the_schema() -> None:
    config = VehicleConfig(broker="mqtt://127.0.0.1", manufacturer="m", serial_number="s")
    sections = report.factsheet_sections(config, list(report.INSTANT_ACTIONS))
    header = {"headerId": 0, "timestamp": report.timestamp(), "version": "2.0.0",
              "manufacturer": "acme", "serialNumber": "r1"}  # fmt: skip
    VALIDATORS["factsheet"].validate({**header, **sections})


async def test_ended_actions_and_their_errors_are_bounded() -> None:
    from galileo_async import connect
    from galileo_async.vda5050 import Vehicle
    from galileo_async.vda5050.actions import MAX_ACTION_ERRORS, MAX_ENDED_ACTIONS
    from galileo_async.vda5050.models import Action

    config = VehicleConfig(broker="mqtt://127.0.0.1", manufacturer="m", serial_number="s")
    async with connect("sim://") as robot:
        vehicle = Vehicle(robot, config)  # not run: nothing is published
        actions = [
            Action(actionId=str(n), actionType="lift" if n % 2 else "stateRequest",
                   blockingType="HARD")
            for n in range(3 * MAX_ENDED_ACTIONS)
        ]  # fmt: skip
        vehicle.actions.queue(actions)
        await vehicle.actions.run(actions)
        states = vehicle.actions.states()
        assert len(states) == MAX_ENDED_ACTIONS
        assert states[-1].actionId == str(3 * MAX_ENDED_ACTIONS - 1)
        assert len(vehicle.actions.errors) == MAX_ACTION_ERRORS
        assert {e.errorType for e in vehicle.errors()} == {"unsupportedAction"}


async def test_a_status_makes_no_state_unless_what_matters_changed(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    from galileo_async import connect
    from galileo_async.vda5050 import Vehicle

    def no_state(vehicle: Vehicle) -> None:
        raise AssertionError("a state was built for a status")

    monkeypatch.setattr(Vehicle, "state", no_state)
    config = VehicleConfig(broker="mqtt://127.0.0.1", manufacturer="m", serial_number="s")
    async with connect("sim://") as robot:
        vehicle = Vehicle(robot, config)  # not run: the statuses are given by hand
        changes: list[int] = []
        monkeypatch.setattr(vehicle, "changed", lambda: changes.append(1))
        report._battery_step.cache_clear()
        for n in range(100):  # moving, the same battery step: one state (the first)
            vehicle._on_status(status(current_pose_x=n / 100, power=25.0))
        assert len(changes) == 1
        assert report._battery_step.cache_info().hits == 99  # not worked out per status
        vehicle._on_status(status(current_speed_x=0.0, current_speed_theta=0.0))
        vehicle._on_status(status(current_speed_x=0.0, current_speed_theta=0.0, power=27.9))
        vehicle._on_status(status(current_speed_x=0.0, current_speed_theta=0.0, power=27.9))
        assert len(changes) == 3  # driving stopped, then the battery step changed
