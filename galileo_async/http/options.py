"""http:// and https:// URLs and their options, checked before anything opens."""

from __future__ import annotations

from collections.abc import Collection, Mapping
from typing import Any
from urllib.parse import parse_qs, unquote, urlsplit

from pydantic import SecretStr

from .._checks import check_names, check_seconds, hide_secrets
from ..errors import InvalidArgument
from ..transports.options import LINK_OPTIONS, PORTABLE_OPTIONS, check_values

__all__ = [
    "DEFAULT_HTTP_PORT",
    "DEFAULT_PING_INTERVAL",
    "DEFAULT_REQUEST_TIMEOUT",
    "DEFAULT_WS_PORT",
    "HTTP_OPTIONS",
    "HttpAddress",
    "check_http_options",
    "parse_http_url",
    "redact_http_url",
]

DEFAULT_HTTP_PORT = 3546
DEFAULT_WS_PORT = 3547
#: Seconds between the WebSocket pings of our own timer (http.md: about every second).
DEFAULT_PING_INTERVAL = 1.0
#: Seconds one REST call may take before it fails with HttpError (status None).
DEFAULT_REQUEST_TIMEOUT = 5.0
#: Options of an http:// link on top of every link's (LINK_OPTIONS); the portable ones are
#: ignored but for connect_timeout, the WebSocket's opening limit.
HTTP_OPTIONS = (
    "username", "password", "token", "ws_port", "request_timeout", "ping_interval", "layout",
    *PORTABLE_OPTIONS,
)  # fmt: skip


class HttpAddress:
    """Where the API listens (``base_url``) and the login; the password shows as ``***``."""

    def __init__(
        self,
        base_url: str,
        host: str,
        *,
        secure: bool,
        username: str | None = None,
        password: SecretStr | None = None,
        token: SecretStr | None = None,
        ws_port: int = DEFAULT_WS_PORT,
    ) -> None:
        self.base_url = base_url
        self.host = host
        self.secure = secure
        self.username = username
        self.password = password
        self.token = token
        self.ws_port = ws_port

    def __repr__(self) -> str:
        return f"<HttpAddress {self.base_url} user={self.username!r}>"


def redact_http_url(url: str) -> str:
    """``url`` without a password in its user part or a ``token`` / ``password`` in its query."""
    return hide_secrets(url)


def _port(name: str, value: object) -> int:
    try:
        port = int(str(value))
    except ValueError:
        raise InvalidArgument(f"{name} must be a port number, got {value!r}") from None
    if isinstance(value, bool) or not 0 < port < 65536:
        raise InvalidArgument(f"{name} must be a port number (1-65535), got {value!r}")
    return port


def _secret(name: str, value: object) -> SecretStr | None:
    if value is None or isinstance(value, SecretStr):
        return value
    if not isinstance(value, str) or not value:
        raise InvalidArgument(f"{name} must be a non-empty string or None")  # no value shown
    return SecretStr(value)


def parse_http_url(url: str, options: Mapping[str, Any] | None = None) -> HttpAddress:
    """``http[s]://[user:password@]host[:port][?token=…&ws_port=…]`` plus options → address.

    Options win over the URL. InvalidArgument (never showing a secret) when malformed.
    """
    shown = redact_http_url(url)
    parts = urlsplit(url)
    scheme = parts.scheme.lower()
    if scheme not in ("http", "https") or not parts.hostname:
        raise InvalidArgument(f"not an http[s]://host[:port] URL: {shown!r}")
    try:
        port = parts.port or DEFAULT_HTTP_PORT
    except ValueError:
        raise InvalidArgument(f"bad port in {shown!r}") from None
    given: dict[str, Any] = {}
    for key, values in parse_qs(parts.query).items():
        if key not in ("token", "ws_port", "username", "password"):
            raise InvalidArgument(f"unknown option {key!r} in {shown!r}")
        given[key] = values[-1]
    if parts.username:
        given["username"] = unquote(parts.username)
    if parts.password:
        given["password"] = unquote(parts.password)
    given.update({k: v for k, v in (options or {}).items() if k in given or k in HTTP_OPTIONS})
    username = given.get("username")
    if username is not None and not (isinstance(username, str) and username):
        raise InvalidArgument(f"username must be a non-empty string or None, got {username!r}")
    host = f"[{parts.hostname}]" if ":" in parts.hostname else parts.hostname
    return HttpAddress(
        f"{scheme}://{host}:{port}",
        host,
        secure=scheme == "https",
        username=username,
        password=_secret("password", given.get("password")),
        token=_secret("token", given.get("token")),
        ws_port=_port("ws_port", given.get("ws_port", DEFAULT_WS_PORT)),
    )


def check_http_options(url: str, options: Mapping[str, Any], *, also: Collection[str] = ()) -> None:
    """Raise InvalidArgument for a bad http[s]:// URL, an unknown option or a bad value."""
    check_names(options, {*LINK_OPTIONS, *HTTP_OPTIONS, *also})
    parse_http_url(url, options)
    for name in ("request_timeout", "ping_interval"):
        if name in options:
            check_seconds(name, options[name])
    layout = options.get("layout")
    if layout is not None and str(layout) != "ros":
        raise InvalidArgument(f"layout {layout!r} does not apply to http:// (JSON, by name)")
    check_values({k: v for k, v in options.items() if k in LINK_OPTIONS or k == "connect_timeout"})
