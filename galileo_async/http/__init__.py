"""The vendor's HTTP API (REST on 3546) and WebSocket status (3547): ``http://`` links.

Needs the extra ``http`` (aiohttp): ``pip install 'galileo-async[http]'``.
"""

from __future__ import annotations

from typing import Any

from .calls import REST_CALLS, rest_call
from .channel import STATUS_TOPIC, HttpChannel
from .client import API_PATH, HttpApi
from .options import (
    DEFAULT_HTTP_PORT,
    DEFAULT_WS_PORT,
    HTTP_OPTIONS,
    HttpAddress,
    check_http_options,
    parse_http_url,
    redact_http_url,
)
from .status import status_from_json

__all__ = [
    "API_PATH",
    "DEFAULT_HTTP_PORT",
    "DEFAULT_WS_PORT",
    "HTTP_OPTIONS",
    "REST_CALLS",
    "STATUS_TOPIC",
    "HttpAddress",
    "HttpApi",
    "HttpChannel",
    "check_http_options",
    "http_channel",
    "parse_http_url",
    "redact_http_url",
    "rest_call",
    "status_from_json",
]

_IGNORED = (
    "baudrate",
    "serial_options",
    "layout",
    "username",
    "password",
    "token",
    "ws_port",
    "ca_file",
)


def http_channel(url: str, options: dict[str, Any]) -> HttpChannel:
    """The channel of ``http[s]://host[:port]``; ``options``: checked, without the Link's."""
    address = parse_http_url(url, options)
    kept = {k: v for k, v in options.items() if k not in _IGNORED}
    return HttpChannel(address, name=url, **kept)
