"""Metrics: a Prometheus collector that follows robots and fleets and reads them at scrape time."""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator

from prometheus_client.core import (
    CounterMetricFamily,
    GaugeMetricFamily,
    Metric,
    StateSetMetricFamily,
)
from prometheus_client.registry import Collector

from ..battery import battery_charge
from ..errors import InvalidArgument
from ..events import (
    ChargeStateChanged,
    ConnectionLostEvent,
    Event,
    GoalAbortedEvent,
    GoalCancelledEvent,
    GoalReached,
    GoalRejectedEvent,
    GoalStalledEvent,
    LinkStaleEvent,
)
from ..fleet import Fleet
from ..models import ChargeStatus, GalileoStatus, LinkState, _wire_pose_x, _wire_pose_y
from ..robot import Robot

__all__ = ["GOAL_ENDINGS", "ODOMETER_JUMP", "ODOMETER_STEP", "Metrics"]

#: The ``ending`` label's values: the goal rule's four ends, and a stall the driver cancelled.
GOAL_ENDINGS: dict[type[Event], str] = {
    GoalReached: "reached",
    GoalAbortedEvent: "aborted",
    GoalRejectedEvent: "rejected",
    GoalCancelledEvent: "cancelled",
    GoalStalledEvent: "stalled",
}
#: Metres the pose must move from the last counted point before the odometer adds the move
#: (a standing robot's localisation jitter adds nothing).
ODOMETER_STEP = 0.05
#: Metres between the last counted point and one status's pose beyond which the move is a
#: jump (relocalisation, or the pose of a robot unseen for long): not counted, the count
#: starts again from the new pose. A robot at 0.8 m/s moves 0.03 m between 30 Hz statuses.
ODOMETER_JUMP = 1.0

_STATES = tuple(state.value for state in LinkState)


class _Followed:
    """One robot's listeners and what they count (the link counts the rest itself)."""

    __slots__ = (
        "charge_cycles", "endings", "lost", "metres", "name", "robot", "stale", "x", "y",
    )  # fmt: skip

    def __init__(self, name: str, robot: Robot) -> None:
        self.name = name
        self.robot = robot
        self.metres = 0.0
        # The last counted point (NaN: none yet).
        self.x = math.nan
        self.y = math.nan
        self.charge_cycles = 0
        self.stale = 0
        self.lost = 0
        self.endings = dict.fromkeys(GOAL_ENDINGS.values(), 0)

    def start(self) -> None:
        self.robot.add_update_listener(self.update)
        self.robot.add_event_listener(self.event)

    def stop(self) -> None:
        self.robot.remove_update_listener(self.update)
        self.robot.remove_event_listener(self.event)

    def update(self, status: GalileoStatus) -> None:
        """The odometer: the pose's moves of ODOMETER_STEP or more, jumps left out (per frame)."""
        x, y = _wire_pose_x(status), _wire_pose_y(status)
        if x is None or y is None:
            return
        dx, dy = x - self.x, y - self.y
        moved = dx * dx + dy * dy
        if moved < ODOMETER_STEP * ODOMETER_STEP:
            return
        # With no point yet (NaN), both tests are False: the first pose is the first point.
        if moved <= ODOMETER_JUMP * ODOMETER_JUMP:
            self.metres += math.sqrt(moved)
        self.x, self.y = x, y

    def event(self, event: Event) -> None:
        kind = type(event)
        ending = GOAL_ENDINGS.get(kind)
        if ending is not None:
            self.endings[ending] += 1
        elif kind is LinkStaleEvent:
            self.stale += 1
        elif kind is ConnectionLostEvent:
            self.lost += 1
        elif kind is ChargeStateChanged:
            assert isinstance(event, ChargeStateChanged)
            # CHARGED → CHARGING is the trickle charge of the same cycle.
            if event.new is ChargeStatus.CHARGING and event.old is not ChargeStatus.CHARGED:
                self.charge_cycles += 1


class Metrics(Collector):
    """The robots it follows, as Prometheus metrics with the label ``robot``.

    Register it on a prometheus_client registry (``serve_metrics`` does) or call
    ``collect()``; it reads the robots on the caller's thread, so collect on the robots'
    event loop. Per status it only adds to an odometer; the rest is read at scrape time.
    """

    def __init__(self) -> None:
        self._robots: dict[str, _Followed] = {}
        self._fleets: list[Fleet] = []

    def add_robot(self, robot: Robot, *, name: str) -> None:
        """Follow ``robot`` as ``robot="name"`` (a fleet name or URL); InvalidArgument if taken."""
        if not name:
            raise InvalidArgument("a robot's metrics need a name")
        if name in self._robots or any(name in fleet for fleet in self._fleets):
            raise InvalidArgument(f"metrics already follow a robot named {name!r}")
        followed = self._robots[name] = _Followed(name, robot)
        followed.start()

    def remove_robot(self, name: str) -> None:
        """Stop following robot ``name`` (added alone or by a fleet); its series go."""
        followed = self._robots.pop(name, None)
        if followed is not None:
            followed.stop()

    def add_fleet(self, fleet: Fleet) -> None:
        """Follow every robot of ``fleet`` by its name, those that connect later too."""
        taken = [name for name in fleet.names if name in self._robots]
        if taken or any(fleet is known for known in self._fleets):
            raise InvalidArgument(f"metrics already follow {', '.join(map(repr, taken)) or fleet}")
        self._fleets.append(fleet)
        fleet.add_connect_listener(self._joined, connected=True)

    def remove_fleet(self, fleet: Fleet) -> None:
        """Stop following ``fleet`` and its robots."""
        for index, known in enumerate(self._fleets):
            if known is fleet:
                del self._fleets[index]
                fleet.remove_connect_listener(self._joined)
                for name in fleet.names:
                    self.remove_robot(name)
                return

    def close(self) -> None:
        """Stop following everything (the robots' listeners are removed)."""
        for fleet in list(self._fleets):
            self.remove_fleet(fleet)
        for name in list(self._robots):
            self.remove_robot(name)

    @property
    def names(self) -> tuple[str, ...]:
        """The ``robot`` label of every robot followed (a fleet's unconnected ones too)."""
        names = dict.fromkeys(self._robots)
        for fleet in self._fleets:
            names.update(dict.fromkeys(fleet.names))
        return tuple(names)

    def odometer(self, name: str) -> float:
        """Metres robot ``name`` drove since it was followed (KeyError if not followed)."""
        return self._robots[name].metres

    def _joined(self, name: str, robot: Robot) -> None:
        if name not in self._robots:
            followed = self._robots[name] = _Followed(name, robot)
            followed.start()

    def _states(self) -> Iterator[tuple[str, LinkState]]:
        """Each followed name with its link state (a fleet's robot not connected yet too)."""
        for fleet in self._fleets:
            for name in fleet.names:
                if name not in self._robots:
                    yield name, fleet.state(name)
        for name, followed in self._robots.items():
            yield name, followed.robot.link_state

    def collect(self) -> Iterator[Metric]:
        """The metrics now, one family per step (the registry calls it at each scrape).

        Each family is read when it is reached: a caller may let the loop run between two
        (serve_metrics does), so two families can be a few milliseconds apart.
        """
        state = StateSetMetricFamily(
            "galileo_link_state", "The link's state (LinkState).", labels=["robot"]
        )
        for name, now in self._states():
            state.add_metric([name], {value: now.value == value for value in _STATES})
        yield state
        connected = GaugeMetricFamily(
            "galileo_link_connected", "1 while the link's transport is open.", labels=["robot"]
        )
        for name, _ in self._states():
            followed = self._robots.get(name)
            is_open = followed is not None and followed.robot.link.connected
            connected.add_metric([name], 1.0 if is_open else 0.0)
        yield connected
        for name, doc, read in _COUNTERS:
            family = CounterMetricFamily(name, doc, labels=["robot"])
            for robot, followed in self._robots.items():
                family.add_metric([robot], read(followed))
            yield family
        endings = CounterMetricFamily(
            "galileo_goals_ended", "Goals ended, by ending.", labels=["robot", "ending"]
        )
        for robot, followed in self._robots.items():
            for ending, count in followed.endings.items():
                endings.add_metric([robot, ending], count)
        yield endings
        for name, doc, gauge in _GAUGES:
            reading = GaugeMetricFamily(name, doc, labels=["robot"])
            for robot, followed in self._robots.items():
                value = gauge(followed)
                if value is not None:
                    reading.add_metric([robot], value)
            yield reading


def _volts(followed: _Followed) -> float | None:
    status = followed.robot.status
    return None if status is None else status.power


def _percent(followed: _Followed) -> float | None:
    volts = _volts(followed)
    return None if volts is None else battery_charge(volts)


#: The counters read per robot: name (without _total), help, how to read it.
_COUNTERS: tuple[tuple[str, str, Callable[[_Followed], float]], ...] = (
    ("galileo_frames_received", "Valid status frames received.",
     lambda f: f.robot.link.frames),
    ("galileo_frames_lost", "Frames missing from the time_stamp sequence.",
     lambda f: f.robot.link.lost_frames),
    ("galileo_link_stale", "Times the link went stale (LinkStale events).", lambda f: f.stale),
    ("galileo_link_lost", "Times the connection was lost (ConnectionLost events).",
     lambda f: f.lost),
    ("galileo_commands_sent", "Commands written to the robot.",
     lambda f: f.robot.link.commands_sent),
    ("galileo_commands_superseded",
     "Queued commands dropped unwritten: replaced by a later one or withdrawn by a stop.",
     lambda f: f.robot.link.commands_superseded),
    ("galileo_odometer_meters", "Metres driven, summed from the status poses (jumps left out).",
     lambda f: f.metres),
    ("galileo_charge_cycles", "Charging starts (charge_status to charging).",
     lambda f: f.charge_cycles),
)  # fmt: skip
#: The gauges read per robot (None: no sample for that robot yet).
_GAUGES: tuple[tuple[str, str, Callable[[_Followed], float | None]], ...] = (
    ("galileo_battery_volts", "Battery voltage (the status's power).", _volts),
    ("galileo_battery_percent",
     "Estimated battery charge, 0 to 100, from the voltage (galileo_async.battery).", _percent),
    ("galileo_last_frame_age_seconds", "Seconds since the last valid frame.",
     lambda f: f.robot.link.last_frame_age),
)  # fmt: skip
