"""Vehicle settings (VehicleConfig) and the broker URL form: pure, no I/O."""

from __future__ import annotations

import math
from dataclasses import dataclass
from urllib.parse import unquote, urlsplit

from ..errors import InvalidArgument

__all__ = [
    "MAX_VISUALIZATION_RATE",
    "BrokerAddress",
    "VehicleConfig",
    "parse_broker_url",
]

#: The robot reports 30 status frames per second (PROTOCOL.md §1): faster says nothing new.
MAX_VISUALIZATION_RATE = 30.0
_DEFAULT_PORTS = {"mqtt": 1883, "mqtts": 8883}


@dataclass(frozen=True)
class BrokerAddress:
    """Where the MQTT broker listens and how to log in."""

    host: str
    port: int
    tls: bool = False
    username: str | None = None
    password: str | None = None


def parse_broker_url(url: str) -> BrokerAddress:
    """Parse ``mqtt://[user:password@]host[:port]`` or ``mqtts://…`` (TLS); InvalidArgument."""
    if not isinstance(url, str) or not url:
        raise InvalidArgument(f"broker URL must be a non-empty string, got {url!r}")
    parts = urlsplit(url)
    if parts.scheme not in _DEFAULT_PORTS:
        raise InvalidArgument(f"broker URL must start with mqtt:// or mqtts://, got {url!r}")
    try:
        port = parts.port or _DEFAULT_PORTS[parts.scheme]
    except ValueError:
        raise InvalidArgument(f"broker URL has a bad port: {url!r}") from None
    if not parts.hostname:
        raise InvalidArgument(f"broker URL names no host: {url!r}")
    if parts.path not in ("", "/") or parts.query or parts.fragment:
        raise InvalidArgument(f"broker URL takes no path or query: {url!r}")
    return BrokerAddress(
        host=parts.hostname,
        port=port,
        tls=parts.scheme == "mqtts",
        username=unquote(parts.username) if parts.username is not None else None,
        password=unquote(parts.password) if parts.password is not None else None,
    )


def _check_name(name: str, value: str) -> None:
    # Topic levels must not contain MQTT wildcards or separators (VDA 5050 §6.1).
    if not isinstance(value, str) or not value or any(c in value for c in "/#+"):
        raise InvalidArgument(f"{name} must be a non-empty string without / # +, got {value!r}")


def _check_seconds(name: str, value: float, *, allow_zero: bool = False) -> None:
    ok = isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
    if not ok or value < 0 or (value == 0 and not allow_zero):
        raise InvalidArgument(f"{name} must be a finite number of seconds > 0, got {value!r}")


@dataclass(frozen=True)
class VehicleConfig:
    """One VDA 5050 vehicle: broker, identity, rates and limits (validated on creation)."""

    broker: str
    manufacturer: str
    serial_number: str
    interface_name: str = "uagv"
    #: The mapId of agvPosition and the only mapId orders may use.
    map_id: str = "map"
    #: visualization messages per second (at most MAX_VISUALIZATION_RATE); 0: none.
    visualization_rate: float = 10.0
    #: state is published on every change that matters and at least this often.
    state_interval: float = 30.0
    #: An order still running after the broker has been gone this long is cancelled.
    broker_loss_stop_delay: float = 5.0
    #: Metres: the first node's default allowedDeviationXY.
    default_deviation_xy: float = 0.5
    #: Reconnect back-off to the broker: first and largest delay in seconds.
    reconnect_initial: float = 0.5
    reconnect_max: float = 10.0
    #: MQTT keep-alive in seconds (the broker declares the vehicle lost after 1.5 x this).
    keepalive: int = 10
    #: CA certificate file for mqtts:// (None: the system's trust store).
    tls_ca_file: str | None = None
    #: The robot's top speed in m/s for the factsheet (the serial link cannot read it).
    max_speed: float = 0.8
    #: Open navigation when the vehicle starts.
    start_navigation: bool = False

    def __post_init__(self) -> None:
        parse_broker_url(self.broker)
        _check_name("manufacturer", self.manufacturer)
        _check_name("serial_number", self.serial_number)
        _check_name("interface_name", self.interface_name)
        if not isinstance(self.map_id, str) or not self.map_id:
            raise InvalidArgument(f"map_id must be a non-empty string, got {self.map_id!r}")
        rate = self.visualization_rate
        _check_seconds("visualization_rate", rate, allow_zero=True)
        if rate > MAX_VISUALIZATION_RATE:
            raise InvalidArgument(
                f"visualization_rate must be at most {MAX_VISUALIZATION_RATE:g} Hz "
                f"(the robot's status rate), got {rate!r}"
            )
        for name in ("state_interval", "broker_loss_stop_delay", "reconnect_initial"):
            _check_seconds(name, getattr(self, name))
        _check_seconds("default_deviation_xy", self.default_deviation_xy, allow_zero=True)
        _check_seconds("reconnect_max", self.reconnect_max)
        if self.reconnect_max < self.reconnect_initial:
            raise InvalidArgument("reconnect_max must be >= reconnect_initial")
        if isinstance(self.keepalive, bool) or not isinstance(self.keepalive, int):
            raise InvalidArgument(f"keepalive must be whole seconds, got {self.keepalive!r}")
        if self.keepalive < 1:
            raise InvalidArgument(f"keepalive must be >= 1 s, got {self.keepalive!r}")

    @property
    def address(self) -> BrokerAddress:
        """The parsed broker URL."""
        return parse_broker_url(self.broker)

    def topic(self, name: str) -> str:
        """``{interfaceName}/v2/{manufacturer}/{serialNumber}/{name}`` (VDA 5050 §6.1)."""
        return f"{self.interface_name}/v2/{self.manufacturer}/{self.serial_number}/{name}"
