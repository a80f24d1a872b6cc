"""Vehicle settings (VehicleConfig) and the broker URL form: pure, no I/O."""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from urllib.parse import unquote, urlsplit

from pydantic import SecretStr

from ..errors import InvalidArgument

__all__ = [
    "MAX_VISUALIZATION_RATE",
    "REDACTED",
    "BrokerAddress",
    "VehicleConfig",
    "parse_broker_url",
    "redact_url",
]

#: The robot reports 30 status frames per second (docs/protocol.md §1): faster says nothing new.
MAX_VISUALIZATION_RATE = 30.0
_DEFAULT_PORTS = {"mqtt": 1883, "mqtts": 8883}
#: What a password is shown as in URLs, reprs, logs and error messages.
REDACTED = "***"


@dataclass(frozen=True)
class BrokerAddress:
    """Where the MQTT broker listens and how to log in (the password never shows in repr)."""

    host: str
    port: int
    tls: bool = False
    username: str | None = None
    password: SecretStr | None = None


def redact_url(url: str) -> str:
    """``url`` with everything between the user name and the last ``@`` shown as ``***``."""
    scheme, sep, rest = url.partition("://")
    if not sep:
        scheme, rest = "", url
    # The last "@" and the first ":" before it: a password with a raw "@" or "/" is hidden too.
    userinfo, at, host = rest.rpartition("@")
    user, colon, _password = userinfo.partition(":")
    if not at or not colon:
        return url
    return f"{scheme}{sep}{user}:{REDACTED}@{host}"


def parse_broker_url(url: str) -> BrokerAddress:
    """Parse ``mqtt://[user[:password]@]host[:port]`` or ``mqtts://…`` (TLS); InvalidArgument.

    Error messages show the URL with its password as ``***``.
    """
    if not isinstance(url, str) or not url:
        raise InvalidArgument(f"broker URL must be a non-empty string, got {url!r}")
    shown = redact_url(url)
    try:
        parts = urlsplit(url)
        port = parts.port
    except ValueError:
        raise InvalidArgument(f"broker URL is malformed or has a bad port: {shown!r}") from None
    if parts.scheme not in _DEFAULT_PORTS:
        raise InvalidArgument(f"broker URL must start with mqtt:// or mqtts://, got {shown!r}")
    if not parts.hostname:
        raise InvalidArgument(f"broker URL names no host: {shown!r}")
    if parts.path not in ("", "/") or parts.query or parts.fragment:
        raise InvalidArgument(f"broker URL takes no path or query: {shown!r}")
    password = unquote(parts.password) if parts.password is not None else None
    return BrokerAddress(
        host=parts.hostname,
        port=port or _DEFAULT_PORTS[parts.scheme],
        tls=parts.scheme == "mqtts",
        username=unquote(parts.username) if parts.username is not None else None,
        password=None if password is None else SecretStr(password),
    )


def _check_name(name: str, value: str) -> None:
    # Topic levels must not contain MQTT wildcards or separators (VDA 5050 §6.1).
    if not isinstance(value, str) or not value or any(c in value for c in "/#+"):
        raise InvalidArgument(f"{name} must be a non-empty string without / # +, got {value!r}")


def _check_seconds(name: str, value: float, *, allow_zero: bool = False) -> None:
    ok = isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
    if not ok or value < 0 or (value == 0 and not allow_zero):
        raise InvalidArgument(f"{name} must be a finite number of seconds > 0, got {value!r}")


def _check_file(name: str, value: str | None) -> None:
    if value is not None and (not isinstance(value, str) or not value):
        raise InvalidArgument(f"{name} must be a file path (str) or None, got {value!r}")


_PHYSICAL = ("width", "length", "height_min", "height_max", "acceleration_max", "deceleration_max")


def _check_physical(name: str, value: float) -> None:
    ok = isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
    if not ok or value < 0:
        raise InvalidArgument(f"{name} must be a finite number >= 0, got {value!r}")


@dataclass(frozen=True, repr=False)
class VehicleConfig:
    """One VDA 5050 vehicle: broker, identity, rates and limits (validated on creation).

    The password (``password``, or in the broker URL) shows as ``***`` in repr and str.
    """

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
    #: None (VDA 5050 §6.2): without a broker the order goes on to its last released node.
    #: Seconds: an order still running after the broker has been gone this long is cancelled.
    broker_loss_stop_delay: float | None = None
    #: Metres: the first node's default allowedDeviationXY.
    default_deviation_xy: float = 0.5
    #: Reconnect back-off to the broker: first and largest delay in seconds.
    reconnect_initial: float = 0.5
    reconnect_max: float = 0.8
    #: MQTT keep-alive in seconds (the broker declares the vehicle lost after 1.5 x this).
    keepalive: int = 10
    #: CA certificate file for mqtts:// (None: the system's trust store).
    tls_ca_file: str | None = None
    #: Client certificate (PEM) for mqtts:// brokers that require one (mutual TLS).
    tls_cert_file: str | None = None
    #: The client certificate's private key (PEM, unencrypted); None: it is in tls_cert_file.
    tls_key_file: str | None = None
    #: The broker password, kept apart from the URL (a str is wrapped in a SecretStr).
    password: SecretStr | str | None = None
    #: The robot's top speed in m/s for the factsheet (the serial link cannot read it).
    max_speed: float = 0.8
    #: Open navigation when the vehicle starts.
    start_navigation: bool = False
    #: The VDA 5050 version spoken: "2.0" or "2.1" (topics stay ``…/v2/…``).
    vda_version: str = "2.0"
    #: The factsheet's physicalParameters: metres and m/s² of this robot (the link cannot
    #: read them); 0 where not given.
    width: float = 0.0
    length: float = 0.0
    height_min: float = 0.0
    height_max: float = 0.0
    acceleration_max: float = 0.0
    deceleration_max: float = 0.0
    #: More broker URLs: when the session is lost or a connect fails, the vehicle moves to
    #: the next of ``broker``, these, ``broker`` again … (round robin, with the back-off).
    fallback_brokers: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        self._check_fallbacks()
        self._check_credentials()
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
        for name in ("state_interval", "reconnect_initial"):
            _check_seconds(name, getattr(self, name))
        if self.broker_loss_stop_delay is not None:
            _check_seconds("broker_loss_stop_delay", self.broker_loss_stop_delay)
        _check_seconds("default_deviation_xy", self.default_deviation_xy, allow_zero=True)
        _check_seconds("reconnect_max", self.reconnect_max)
        if self.vda_version not in ("2.0", "2.1"):
            raise InvalidArgument(f"vda_version must be '2.0' or '2.1', got {self.vda_version!r}")
        for name in _PHYSICAL:
            _check_physical(name, getattr(self, name))
        if self.height_max < self.height_min:
            raise InvalidArgument("height_max must be >= height_min")
        if self.reconnect_max < self.reconnect_initial:
            raise InvalidArgument("reconnect_max must be >= reconnect_initial")
        if isinstance(self.keepalive, bool) or not isinstance(self.keepalive, int):
            raise InvalidArgument(f"keepalive must be whole seconds, got {self.keepalive!r}")
        if self.keepalive < 1:
            raise InvalidArgument(f"keepalive must be >= 1 s, got {self.keepalive!r}")

    def _check_fallbacks(self) -> None:
        if isinstance(self.fallback_brokers, str) or not isinstance(
            self.fallback_brokers, (tuple, list)
        ):
            kind = type(self.fallback_brokers).__name__
            raise InvalidArgument(f"fallback_brokers must be a tuple of URLs, got a {kind}")
        object.__setattr__(self, "fallback_brokers", tuple(self.fallback_brokers))  # frozen
        seen = {self._where(parse_broker_url(self.broker))}
        for url in self.fallback_brokers:
            where = self._where(parse_broker_url(url))
            if where in seen:
                raise InvalidArgument(f"broker {redact_url(url)!r} is given twice")
            seen.add(where)

    @staticmethod
    def _where(address: BrokerAddress) -> tuple[str, int]:
        return address.host, address.port

    def _check_credentials(self) -> None:
        if isinstance(self.password, str):
            object.__setattr__(self, "password", SecretStr(self.password))  # frozen
        elif self.password is not None and not isinstance(self.password, SecretStr):
            kind = type(self.password).__name__
            raise InvalidArgument(f"password must be a str or a SecretStr, got a {kind}")
        for each in self.urls():
            if self.password is not None and each.password is not None:
                raise InvalidArgument("the broker URL has a password and password is given too")
            if (self.password is not None or each.password is not None) and not each.username:
                raise InvalidArgument(
                    "a broker password needs a user name in the URL: mqtt://user@host"
                )
        for name in ("tls_ca_file", "tls_cert_file", "tls_key_file"):
            _check_file(name, getattr(self, name))
        if self.tls_key_file is not None and self.tls_cert_file is None:
            raise InvalidArgument("tls_key_file needs tls_cert_file (the client certificate)")
        tls_files = (self.tls_ca_file, self.tls_cert_file, self.tls_key_file)
        if not any(each.tls for each in self.urls()) and any(p is not None for p in tls_files):
            raise InvalidArgument("TLS files need an mqtts:// broker URL (mqtt:// is plain TCP)")

    def __repr__(self) -> str:
        values = {field.name: getattr(self, field.name) for field in fields(self)}
        values["broker"] = redact_url(self.broker)
        values["fallback_brokers"] = tuple(redact_url(url) for url in self.fallback_brokers)
        return f"VehicleConfig({', '.join(f'{k}={v!r}' for k, v in values.items())})"

    def urls(self) -> list[BrokerAddress]:
        """The parsed URLs of ``broker`` and the ``fallback_brokers``, in turn order."""
        return [parse_broker_url(url) for url in (self.broker, *self.fallback_brokers)]

    @property
    def address(self) -> BrokerAddress:
        """The first broker to connect to (``broker``): see addresses."""
        return self.addresses[0]

    @property
    def addresses(self) -> list[BrokerAddress]:
        """Every broker in turn order: each URL's host and user, the password from either place."""
        if self.password is None:
            return self.urls()
        password = self.password if isinstance(self.password, SecretStr) else None
        return [BrokerAddress(u.host, u.port, u.tls, u.username, password) for u in self.urls()]

    def topic(self, name: str) -> str:
        """``{interfaceName}/v2/{manufacturer}/{serialNumber}/{name}`` (VDA 5050 §6.1)."""
        return f"{self.interface_name}/v2/{self.manufacturer}/{self.serial_number}/{name}"
