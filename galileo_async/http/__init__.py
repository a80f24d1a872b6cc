"""The vendor's HTTP API (REST on 3546) and WebSocket status (3547): ``http://`` links.

Needs the extra ``http`` (aiohttp): ``pip install 'galileo-async[http]'``.
"""

from __future__ import annotations

from typing import Any

from ..transports.stats import StatusSink
from .client import API_PATH, HttpApi
from .link import STATUS_TOPIC, HttpLink
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
    "STATUS_TOPIC",
    "HttpAddress",
    "HttpApi",
    "HttpLink",
    "check_http_options",
    "open_http_link",
    "parse_http_url",
    "redact_http_url",
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


def open_http_link(url: str, store: StatusSink, **options: Any) -> HttpLink:
    """An HttpLink (not yet opened) for ``http[s]://host[:port]``; options as HttpLink's."""
    check_http_options(url, options)
    address = parse_http_url(url, options)
    kept = {k: v for k, v in options.items() if k not in _IGNORED}
    return HttpLink(store, address, name=url, **kept)
