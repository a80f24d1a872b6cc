"""http:// and https:// URLs and their options, checked before anything opens."""

from __future__ import annotations

import os
from collections.abc import Collection, Mapping
from typing import Any
from urllib.parse import parse_qs, unquote, urlsplit

from pydantic import SecretStr

from .._checks import hide_secrets
from ..errors import InvalidArgument
from ..options import (
    DEFAULT_PING_INTERVAL,
    DEFAULT_REQUEST_TIMEOUT,
    DEFAULT_WS_PORT,
    check_options,
    names_for,
)
from ..options.checks import check_ca_file

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
#: The options an http:// link takes (galileo_async.options); the portable ones are
#: ignored but for connect_timeout, the WebSocket's opening limit.
HTTP_OPTIONS = tuple(sorted(names_for("http", ("link",))))


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
        ca_file: str | None = None,
    ) -> None:
        self.base_url = base_url
        self.host = host
        self.secure = secure
        self.username = username
        self.password = password
        self.token = token
        self.ws_port = ws_port
        #: The PEM file of the CAs https:// and wss:// trust (None: the system's).
        self.ca_file = ca_file

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
    """``http[s]://[user:password@]host[:port][?token=…&ws_port=…&ca_file=…]`` + options → address.

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
        if key not in ("token", "ws_port", "username", "password", "ca_file"):
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
    ca_file = given.get("ca_file")
    check_ca_file("ca_file", ca_file)
    if ca_file is not None and scheme != "https":
        raise InvalidArgument(f"ca_file applies to https:// only, not to {shown!r}")
    host = f"[{parts.hostname}]" if ":" in parts.hostname else parts.hostname
    return HttpAddress(
        f"{scheme}://{host}:{port}",
        host,
        secure=scheme == "https",
        username=username,
        password=_secret("password", given.get("password")),
        token=_secret("token", given.get("token")),
        ws_port=_port("ws_port", given.get("ws_port", DEFAULT_WS_PORT)),
        ca_file=None if ca_file is None else os.fspath(ca_file),
    )


def check_http_options(
    url: str,
    options: Mapping[str, Any],
    *,
    also: Collection[str] = (),
    owners: Collection[str] = ("link",),
) -> None:
    """Raise InvalidArgument for a bad http[s]:// URL, an option it does not take or a bad value."""
    check_options("http", options, owners=owners, also=also)
    parse_http_url(url, options)
