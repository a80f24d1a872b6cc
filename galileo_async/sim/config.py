"""Simulator options (SimConfig, Faults) and the ``sim://`` URL form."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any, Literal
from urllib.parse import parse_qsl, urlsplit

from .._checks import check_number
from ..errors import InvalidArgument
from ..models import StatusLayout
from ..protocol import LAYOUTS, UDP_LAYOUTS

__all__ = ["DEFAULT_TARGETS", "FRAME_RATE", "Faults", "SimConfig", "parse_sim_url"]

#: Status frames per second of simulated time (docs/protocol.md §1).
FRAME_RATE = 30
#: The default map: six targets spread over a ~10 m area around the start pose (0, 0).
DEFAULT_TARGETS: tuple[tuple[float, float], ...] = (
    (2.0, 0.0),
    (4.0, 3.0),
    (0.0, 5.0),
    (-3.0, 2.0),
    (-4.0, -3.0),
    (3.0, -4.0),
)

Firmware = Literal["real", "document"]
_SERIAL_LAYOUTS = tuple(LAYOUTS)
_UDP_LAYOUTS = tuple(UDP_LAYOUTS)


def _check_fraction(name: str, value: float) -> None:
    check_number(name, value, low=0.0, high=1.0)


def _check_non_negative(name: str, value: float) -> None:
    check_number(name, value, low=0.0)


def _check_point(name: str, value: object, size: int) -> tuple[float, ...]:
    """``value`` as ``size`` finite floats; else InvalidArgument."""
    try:
        point = tuple(float(v) for v in value)  # type: ignore[attr-defined]
    except (TypeError, ValueError):
        point = ()
    if len(point) != size or not all(map(math.isfinite, point)):
        raise InvalidArgument(f"{name} must be {size} finite numbers, got {value!r}")
    return point


def _check_points(name: str, value: object, size: int) -> tuple[tuple[float, ...], ...]:
    """``value`` as points of ``size`` finite floats each; else InvalidArgument."""
    try:
        items = list(value)  # type: ignore[call-overload]
    except TypeError:
        raise InvalidArgument(f"{name} must be a sequence of points, got {value!r}") from None
    return tuple(_check_point(f"each of {name}", item, size) for item in items)


@dataclass(frozen=True)
class Faults:
    """Fault injection; every probability is drawn from the simulator's seeded generator."""

    #: Probability per frame and connection of a burst of 1-16 garbage bytes before it.
    garbage: float = 0.0
    #: Fraction of frames not sent to a connection (the time_stamp still advances).
    drop: float = 0.0
    #: Probability per frame and connection that one random bit of the frame is flipped.
    bitflip: float = 0.0
    #: Close each stream connection this many *simulated* seconds after it opened.
    disconnect_after: float | None = None
    #: Probability per goal that the planner gives up half way (free, far from the target);
    #: "next" aborts the next goal only.
    planner_abort: float | Literal["next"] = 0.0
    #: The navigation stack dies this many simulated seconds after a goal starts: the serial
    #: node re-sends its last status with a live time_stamp, and no command has an effect.
    freeze_after: float | None = None
    #: The robot is blocked this many simulated seconds after a goal starts: the goal stays
    #: working, the robot does not move (an obstacle the planner waits behind).
    block_after: float | None = None

    def __post_init__(self) -> None:
        for name in ("garbage", "drop", "bitflip"):
            _check_fraction(name, getattr(self, name))
        for name in ("disconnect_after", "freeze_after", "block_after"):
            if getattr(self, name) is not None:
                _check_non_negative(name, getattr(self, name))
        if self.planner_abort != "next":
            if isinstance(self.planner_abort, str):
                raise InvalidArgument(
                    f"planner_abort must be 0..1 or 'next', got {self.planner_abort!r}"
                )
            _check_fraction("planner_abort", self.planner_abort)

    @property
    def any_stream_fault(self) -> bool:
        """True when frames need per-connection processing."""
        return self.garbage > 0.0 or self.drop > 0.0 or self.bitflip > 0.0


@dataclass(frozen=True)
class SimConfig:
    """Everything that shapes a simulated robot; times are simulated seconds."""

    layout: StatusLayout = StatusLayout.V2
    #: "real": behave like the vendor's published firmware; "document": like its document.
    firmware: Firmware = "real"
    #: Time scale: simulated seconds per real second (30 x speed frames per real second).
    speed: float = 1.0
    targets: tuple[tuple[float, float], ...] = DEFAULT_TARGETS
    seed: int = 0
    visual_init_time: float = 2.0
    #: A start-navigation within this long of the previous one is ignored; None: 10 s on
    #: real firmware, 0 in document mode (docs/protocol.md §2.a).
    start_ignore_time: float | None = None
    busy_on_start: float = 1.0
    busy_on_map_stop: float = 2.0
    busy_on_save: float = 1.0
    #: How long a command waits for busy to end before it is dropped (docs/protocol.md §2).
    busy_max_wait: float = 180.0
    patrol_dwell: float = 3.0
    #: Some firmware versions ignore 'V' 2 (docs/protocol.md §2.h).
    ignore_save_map: bool = False
    #: Several commands in one write keep only the first and last; None: on for real firmware.
    concat_loss: bool | None = None
    max_speed: float = 0.8
    max_turn_rate: float = 1.5
    #: Seconds after the last speed command (f, b, c, d) that the chassis zeroes both
    #: speeds; None: the last speed holds forever, as on 22 of the vendor's chassis builds
    #: (docs/protocol.md §6.5; chitu-noetic stops after 3 s).
    cmd_vel_timeout: float | None = None
    acceleration: float = 1.0
    angular_acceleration: float = 3.0
    arrival_distance: float = 0.005
    start_pose: tuple[float, float, float] = (0.0, 0.0, 0.0)
    dock: tuple[float, float] = (-1.0, 0.0)
    docking_time: float = 2.0
    power: float = 25.0
    #: Volts lost per simulated second (charging adds charge_rate instead).
    power_drain: float = 0.0005
    power_full: float = 28.0
    charge_rate: float = 0.05
    faults: Faults = field(default_factory=Faults)
    #: The status layout of the UDP face (serve_udp): udp_v2 (48 bytes) or udp_v1 (44).
    udp_layout: StatusLayout = StatusLayout.UDP_V2
    #: The UDP face also sends the environment-sensor frame after every third status frame.
    env_sensors: bool = False
    #: A ``galileo record`` capture: every connection gets its bytes (at ``speed``) instead
    #: of the simulated robot's frames; its commands are logged, not acted on.
    replay: str | None = None
    #: The robot of an MCAP ``replay`` recording to play (needed when it holds several).
    robot: str | None = None

    def __post_init__(self) -> None:
        try:
            layout = StatusLayout(self.layout)
            udp_layout = StatusLayout(self.udp_layout)
        except ValueError as exc:
            raise InvalidArgument(f"unknown layout: {exc}") from None
        if layout not in _SERIAL_LAYOUTS:
            raise InvalidArgument(f"the simulator's stream speaks the serial layouts, not {layout}")
        if udp_layout not in _UDP_LAYOUTS:
            raise InvalidArgument(f"udp_layout must be udp_v2 or udp_v1, not {udp_layout}")
        object.__setattr__(self, "layout", layout)
        object.__setattr__(self, "udp_layout", udp_layout)
        if self.firmware not in ("real", "document"):
            raise InvalidArgument(f"firmware must be 'real' or 'document', got {self.firmware!r}")
        check_number("speed", self.speed, low=0.0, low_open=True, high=1000.0)
        if isinstance(self.seed, bool) or not isinstance(self.seed, int):
            raise InvalidArgument(f"seed must be an int, got {self.seed!r}")
        targets = _check_points("targets", self.targets, 2)
        if len(targets) > 256:
            raise InvalidArgument("targets must be at most 256 finite (x, y) pairs")
        object.__setattr__(self, "targets", targets)
        for name in (
            "visual_init_time", "busy_on_start", "busy_on_map_stop", "busy_on_save",
            "busy_max_wait", "patrol_dwell", "docking_time", "power_drain", "charge_rate",
            "arrival_distance", "power", "power_full",
        ):  # fmt: skip
            _check_non_negative(name, getattr(self, name))
        for name in ("start_ignore_time", "cmd_vel_timeout"):
            if getattr(self, name) is not None:
                _check_non_negative(name, getattr(self, name))
        for name, size in (("start_pose", 3), ("dock", 2)):
            object.__setattr__(self, name, _check_point(name, getattr(self, name), size))
        for name in ("max_speed", "max_turn_rate", "acceleration", "angular_acceleration"):
            check_number(name, getattr(self, name), low=0.0, low_open=True)

    @property
    def real_firmware(self) -> bool:
        """True in the default firmware="real" mode."""
        return self.firmware == "real"

    @property
    def effective_start_ignore_time(self) -> float:
        """The start-navigation ignore window actually applied."""
        if self.start_ignore_time is not None:
            return self.start_ignore_time
        return 10.0 if self.real_firmware else 0.0

    @property
    def effective_concat_loss(self) -> bool:
        """Whether commands concatenated in one write lose the middle ones."""
        return self.real_firmware if self.concat_loss is None else self.concat_loss

    def replace(self, **overrides: Any) -> SimConfig:
        """A copy with fields replaced; fault names (drop, garbage, …) go into ``faults``."""
        fault_names = {f.name for f in dataclasses.fields(Faults)}
        fault_overrides = {k: overrides.pop(k) for k in list(overrides) if k in fault_names}
        unknown = set(overrides) - {f.name for f in dataclasses.fields(SimConfig)}
        if unknown:
            raise InvalidArgument(f"unknown simulator option(s): {', '.join(sorted(unknown))}")
        config = dataclasses.replace(self, **overrides) if overrides else self
        if fault_overrides:
            faults = dataclasses.replace(config.faults, **fault_overrides)
            config = dataclasses.replace(config, faults=faults)
        return config


_FLOAT_OPTIONS = frozenset(
    {
        "speed", "visual_init_time", "start_ignore_time", "busy_on_start", "busy_on_map_stop",
        "busy_on_save", "busy_max_wait", "patrol_dwell", "max_speed", "max_turn_rate",
        "acceleration", "angular_acceleration", "arrival_distance", "docking_time", "power",
        "power_drain", "power_full", "charge_rate", "garbage", "drop", "bitflip",
        "disconnect_after", "freeze_after", "block_after",
        "cmd_vel_timeout",
    }
)  # fmt: skip
_BOOL_OPTIONS = frozenset({"ignore_save_map", "concat_loss", "env_sensors"})


def _parse_pairs(name: str, text: str) -> tuple[tuple[float, float], ...]:
    """Parse ``x,y;x,y`` into pairs."""
    pairs = []
    for item in filter(None, text.split(";")):
        parts = item.split(",")
        if len(parts) != 2:
            raise InvalidArgument(f"{name} must look like 'x,y;x,y', got {text!r}")
        pairs.append((float(parts[0]), float(parts[1])))
    return tuple(pairs)


def _parse_value(name: str, text: str) -> Any:
    try:
        if name in _FLOAT_OPTIONS:
            return float(text)
        if name == "seed":
            return int(text)
        if name in _BOOL_OPTIONS:
            lowered = text.lower()
            if lowered not in ("1", "0", "true", "false", "yes", "no", "on", "off"):
                raise ValueError(text)
            return lowered in ("1", "true", "yes", "on")
        if name == "targets":
            return _parse_pairs(name, text)
        if name in ("start_pose", "dock"):
            return tuple(float(part) for part in text.split(","))
        if name == "planner_abort":
            return "next" if text == "next" else float(text)
    except ValueError:
        raise InvalidArgument(f"bad value for simulator option {name}: {text!r}") from None
    return text  # layout, udp_layout, firmware: validated by SimConfig; replay: a path; robot


def parse_sim_url(url: str, base: SimConfig | None = None) -> SimConfig:
    """Parse ``sim://?speed=20&layout=v1&targets=1,2;3,4&drop=0.1`` into a SimConfig."""
    parts = urlsplit(url)
    if parts.scheme != "sim":
        raise InvalidArgument(f"not a sim:// URL: {url!r}")
    options = {name: _parse_value(name, value) for name, value in parse_qsl(parts.query)}
    return (base or SimConfig()).replace(**options)
