"""A Foxglove live view of robots: channels, services, one server (extra [foxglove]).

``FoxgloveServer`` publishes each robot added as ``/name/...`` (pose, transform, status,
link, scene, events; map and map_info on a link with the HTTP API) and serves its goto,
goto_point, stop, cancel, pause, resume and dock services; ``serve_foxglove`` runs one
until cancelled. docs/observability.md, "Foxglove live view", says what a viewer sees.
"""

from __future__ import annotations

from .channels import MAP_FRAME, TOPICS, robot_frame
from .map import MAP_TOPICS
from .relay import LEGACY_SUBPROTOCOL, SDK_SUBPROTOCOL
from .server import DEFAULT_HOST, DEFAULT_PORT, DEFAULT_RATE, FoxgloveServer, serve_foxglove
from .services import SERVICE_TIMEOUT, SERVICES

__all__ = [
    "DEFAULT_HOST",
    "DEFAULT_PORT",
    "DEFAULT_RATE",
    "LEGACY_SUBPROTOCOL",
    "MAP_FRAME",
    "MAP_TOPICS",
    "SDK_SUBPROTOCOL",
    "SERVICES",
    "SERVICE_TIMEOUT",
    "TOPICS",
    "FoxgloveServer",
    "robot_frame",
    "serve_foxglove",
]
