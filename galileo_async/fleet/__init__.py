"""Fleets: many robots in one process, one merged coalesced stream, fleet files (TOML)."""

from __future__ import annotations

from .file import FleetFileError, FleetSpec, fleet_file_robots, load_fleet_file, parse_fleet
from .fleet import (
    DEFAULT_CONNECT_CONCURRENCY,
    DEFAULT_RETRY_INITIAL,
    DEFAULT_RETRY_MAX,
    Fleet,
    FleetConnection,
    FleetEventStream,
    FleetResult,
    FleetStatusStream,
    connect_fleet,
)

__all__ = [
    "DEFAULT_CONNECT_CONCURRENCY",
    "DEFAULT_RETRY_INITIAL",
    "DEFAULT_RETRY_MAX",
    "Fleet",
    "FleetConnection",
    "FleetEventStream",
    "FleetFileError",
    "FleetResult",
    "FleetSpec",
    "FleetStatusStream",
    "connect_fleet",
    "fleet_file_robots",
    "load_fleet_file",
    "parse_fleet",
]
