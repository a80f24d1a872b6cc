"""Fleet files (TOML): ``[robots.NAME] port = "…"`` plus per-robot and shared options.

```toml
targets = "targets.csv"        # optional: known target positions for the map (id,x,y)

[defaults]                     # optional: options of every robot
stale_timeout = 2.0

[robots.alpha]
port = "socket://10.0.0.5:4001"
map_targets = 6

[robots.beta]
port = "/dev/ttyUSB0"
layout = "v1"
serial_number = "B-0042"       # optional: its VDA 5050 serialNumber (default: its name)
manufacturer = "acme"          # optional: its VDA 5050 manufacturer (default: --manufacturer)
```
"""

from __future__ import annotations

import sys
from collections.abc import Collection, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import NoneType, UnionType
from typing import Any, Union, get_args, get_origin

from .._checks import check_names
from ..errors import InvalidArgument
from ..links import scheme_of
from ..options import OPTIONS, Option

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib  # type: ignore[import-not-found]

__all__ = [
    "OPTION_TYPES",
    "VEHICLE_KEYS",
    "FleetFileError",
    "FleetSpec",
    "fleet_file_robots",
    "load_fleet_file",
    "parse_fleet",
]


def _toml_types(hint: Any) -> tuple[type, ...]:
    """The TOML value types an option of type ``hint`` takes (a table for a Mapping; no None)."""
    members = get_args(hint) if get_origin(hint) in (Union, UnionType) else (hint,)
    found: list[type] = []
    for member in members:
        if member is not NoneType:
            origin = get_origin(member) or member
            found.append(dict if issubclass(origin, Mapping) else origin)
    return tuple(found)


#: Options a robot (or ``[defaults]``) may set (every option of connect()), and the TOML
#: types each takes.
OPTION_TYPES: dict[str, tuple[type, ...]] = {
    name: _toml_types(option.type) for name, option in OPTIONS.items()
}
_TOP_LEVEL = ("robots", "defaults", "targets")
#: Keys of a robot's table that are not connect() options: the VDA 5050 identity.
VEHICLE_KEYS = ("serial_number", "manufacturer")


class FleetFileError(InvalidArgument):
    """A fleet file that cannot be used; the message names the file, robot and key."""


@dataclass(frozen=True)
class FleetSpec:
    """A parsed fleet file: URLs by name, options per robot, shared options, targets file."""

    ports: dict[str, str]
    robot_options: dict[str, dict[str, Any]] = field(default_factory=dict)
    defaults: dict[str, Any] = field(default_factory=dict)
    targets: Path | None = None
    #: VDA 5050 identity keys given in robots' tables: {name: {"serial_number": …, …}}.
    vehicle_ids: dict[str, dict[str, str]] = field(default_factory=dict)

    def serial_number(self, name: str) -> str:
        """Robot ``name``'s VDA 5050 serialNumber: its ``serial_number`` key, else its name."""
        return self.vehicle_ids.get(name, {}).get("serial_number", name)

    def manufacturer(self, name: str, default: str) -> str:
        """Robot ``name``'s VDA 5050 manufacturer: its ``manufacturer`` key, else ``default``."""
        return self.vehicle_ids.get(name, {}).get("manufacturer", default)

    def only(self, names: Collection[str]) -> FleetSpec:
        """This fleet with only the robots of ``names`` (in the file's order)."""
        keep = [name for name in self.ports if name in names]
        return FleetSpec(
            {name: self.ports[name] for name in keep},
            {name: self.robot_options[name] for name in keep if name in self.robot_options},
            self.defaults, self.targets,
            {name: self.vehicle_ids[name] for name in keep if name in self.vehicle_ids},
        )  # fmt: skip

    def connect(self, **options: Any) -> Any:
        """``connect_fleet`` for this fleet (``options`` override the file's defaults)."""
        from .fleet import connect_fleet

        return connect_fleet(
            self.ports, robot_options=self.robot_options, **{**self.defaults, **options}
        )


def _scheme_options(ports: Collection[str]) -> dict[str, tuple[type, ...]]:
    """The TOML types of the options the schemes of ``ports`` add (plugins' own options)."""
    own: dict[str, Option] = {}
    for port in ports:
        own.update((option.name, option) for option in scheme_of(port).options)
    return {name: _toml_types(option.type) for name, option in own.items()}


def _check_option(
    where: str, key: str, value: object, extra: Mapping[str, tuple[type, ...]]
) -> Any:
    types = {**OPTION_TYPES, **extra} if extra else OPTION_TYPES
    try:  # a near miss when there is one, as connect() says it; else the known names
        check_names([key], types)
    except InvalidArgument as exc:
        raise FleetFileError(f"{where}: {exc}") from None
    expected = types[key]
    if float in expected and isinstance(value, int) and not isinstance(value, bool):
        return float(value)
    if (bool not in expected and isinstance(value, bool)) or not isinstance(value, expected):
        names = " or ".join("table" if t is dict else t.__name__ for t in expected)
        raise FleetFileError(f"{where}: {key} must be {names}, got {value!r}")
    return value


def _options(
    where: str, table: Mapping[str, Any], extra: Mapping[str, tuple[type, ...]]
) -> dict[str, Any]:
    return {key: _check_option(where, key, value, extra) for key, value in table.items()}


def parse_fleet(
    data: Mapping[str, Any], source: str = "fleet file", base: Path | None = None
) -> FleetSpec:
    """Validate a fleet file's TOML tables; relative paths are taken from ``base``."""
    unknown = [key for key in data if key not in _TOP_LEVEL]
    if unknown:
        raise FleetFileError(
            f"{source}: unknown key {unknown[0]!r} (known: {', '.join(_TOP_LEVEL)})"
        )
    robots = data.get("robots")
    if not isinstance(robots, Mapping) or not robots:
        raise FleetFileError(f'{source}: no robots: add [robots.NAME] tables with port = "…"')
    defaults = data.get("defaults", {})
    if not isinstance(defaults, Mapping):
        raise FleetFileError(f"{source}: [defaults] must be a table")
    ports: dict[str, str] = {}
    robot_options: dict[str, dict[str, Any]] = {}
    vehicle_ids: dict[str, dict[str, str]] = {}
    for name, table in robots.items():
        where = f"{source}: robot {name!r}"
        if not isinstance(table, Mapping):
            raise FleetFileError(f'{where}: must be a table ([robots.{name}] port = "…")')
        port = table.get("port")
        if not isinstance(port, str) or not port:
            raise FleetFileError(f'{where}: port must be a non-empty string (port = "…")')
        ports[name] = port
        ids = {key: table[key] for key in VEHICLE_KEYS if key in table}
        for key, value in ids.items():
            if not isinstance(value, str) or not value:
                raise FleetFileError(f"{where}: {key} must be a non-empty string, got {value!r}")
        if ids:
            vehicle_ids[name] = ids
        extra = _scheme_options([port])
        own = {k: v for k, v in table.items() if k != "port" and k not in VEHICLE_KEYS}
        options = _options(where, own, extra)
        if options:
            robot_options[name] = options
    targets = data.get("targets")
    if targets is not None and not isinstance(targets, str):
        raise FleetFileError(f"{source}: targets must be a path string, got {targets!r}")
    path = None if targets is None else (base or Path()) / targets
    shared = _options(f"{source}: [defaults]", defaults, _scheme_options(ports.values()))
    return FleetSpec(ports, robot_options, shared, path, vehicle_ids)


def _read(file: Path) -> dict[str, Any]:
    try:
        with file.open("rb") as handle:
            data: dict[str, Any] = tomllib.load(handle)
            return data
    except OSError as exc:
        raise FleetFileError(f"{file}: cannot read the fleet file: {exc.strerror or exc}") from None
    except tomllib.TOMLDecodeError as exc:
        raise FleetFileError(f"{file}: not valid TOML: {exc}") from None


def load_fleet_file(path: str | Path, *, robots: Collection[str] | None = None) -> FleetSpec:
    """Read and validate the fleet file at ``path`` (FleetFileError naming what is wrong).

    ``robots``: check and keep only these robots' tables (and the file's other keys), so
    that a mistake in another robot's table does not stop them (``galileo -r NAME``).
    """
    file = Path(path)
    data = _read(file)
    tables = data.get("robots")
    if robots is not None and isinstance(tables, Mapping):
        data = {**data, "robots": {name: tables[name] for name in tables if name in robots}}
    return parse_fleet(data, str(file), file.parent)


def fleet_file_robots(path: str | Path) -> list[str]:
    """The names of the robots of the fleet file at ``path``, their tables unchecked.

    FleetFileError when the file cannot be read or is not TOML.
    """
    tables = _read(Path(path)).get("robots")
    return list(tables) if isinstance(tables, Mapping) else []
