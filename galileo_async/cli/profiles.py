"""Named robots: ``galileo -r NAME`` from the --fleet file or the user's config file.

The config file is ``$XDG_CONFIG_HOME/galileo/config.toml`` (``~/.config/galileo/…``).
It has the fleet file's shape (``[robots.NAME] port = "…"`` with connect options,
and optional ``[defaults]``); a robot of the --fleet file is usable by its name too.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..errors import InvalidArgument
from ..fleet.file import fleet_file_robots, load_fleet_file
from ..robot.options import check_connect_options

__all__ = ["ROBOT_ENV", "Profile", "config_path", "find_profile", "profile_names"]

#: The environment variable that names the robot when neither --robot nor --port is given.
ROBOT_ENV = "GALILEO_ROBOT"


@dataclass(frozen=True)
class Profile:
    """A named robot: its port, its connect options and the file it came from."""

    name: str
    port: str
    options: dict[str, Any] = field(default_factory=dict)
    source: Path | None = None


def config_path() -> Path:
    """``$XDG_CONFIG_HOME/galileo/config.toml``; ``~/.config`` when unset or not absolute."""
    base = os.environ.get("XDG_CONFIG_HOME", "")
    root = Path(base) if base and Path(base).is_absolute() else Path.home() / ".config"
    return root / "galileo" / "config.toml"


def _sources(fleet: Path | None) -> list[Path]:
    """Files searched for a name, in order: the --fleet file, then the config file."""
    found = [] if fleet is None else [fleet]
    config = config_path()
    if config.is_file():
        found.append(config)
    return found


def profile_names(fleet: Path | None = None) -> list[str]:
    """Every robot name known (for completion); unreadable files are skipped."""
    names: list[str] = []
    for path in _sources(fleet):
        try:
            names += [name for name in fleet_file_robots(path) if name not in names]
        except InvalidArgument:
            continue
    return names


def find_profile(name: str, fleet: Path | None = None) -> Profile:
    """The robot ``name`` of the --fleet file or the config file, its options checked.

    InvalidArgument (naming the file) when no file knows it or its options are bad:
    they are checked as connect() checks them, before anything is opened. Only this
    robot's table is checked: a mistake in another robot's is reported when that one is used.
    """
    known: list[str] = []
    for path in _sources(fleet):
        names = fleet_file_robots(path)
        if name not in names:
            known += [other for other in names if other not in known]
            continue
        spec = load_fleet_file(path, robots=[name])
        port = spec.ports[name]
        options = {**spec.defaults, **spec.robot_options.get(name, {})}
        try:
            check_connect_options(port, options)
        except InvalidArgument as exc:
            raise InvalidArgument(f"{path}: robot {name!r}: {exc}") from None
        return Profile(name, port, options, path)
    searched = " or ".join(str(path) for path in _sources(fleet)) or f"{config_path()} (absent)"
    listed = f"; known: {', '.join(known)}" if known else ""
    raise InvalidArgument(f"no robot named {name!r} in {searched}{listed}")
