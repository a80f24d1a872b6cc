"""The vendor's HTTP API (REST on 3546) and WebSocket status (3547): ``http://`` links.

Needs the extra ``http`` (aiohttp): ``pip install 'galileo-async[http]'``.
"""

from __future__ import annotations

from typing import Any

from ..transports.link import Link
from ..transports.options import LINK_OPTIONS
from ..transports.stats import StatusSink
from .calls import REST_CALLS, ApiCall, rest_call
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
    "ApiCall",
    "HttpAddress",
    "HttpApi",
    "HttpChannel",
    "check_http_options",
    "open_http_link",
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


def open_http_link(url: str, store: StatusSink, **options: Any) -> Link:
    """A Link over an HttpChannel (not yet opened) for ``http[s]://host[:port]``."""
    check_http_options(url, options)
    address = parse_http_url(url, options)
    kept = {k: v for k, v in options.items() if k not in _IGNORED}
    link_options = {k: kept.pop(k) for k in LINK_OPTIONS if k in kept}
    return Link(HttpChannel(address, name=url, **kept), store, **link_options)
