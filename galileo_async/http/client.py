"""HttpApi: the vendor's REST API (``/api/v1`` on port 3546) over one aiohttp session."""

from __future__ import annotations

import asyncio
import json
import os
import socket
import ssl
from typing import Any

import aiohttp
from pydantic import SecretStr

from ..errors import AuthenticationError, ConnectionLost, HttpError, HttpTimeout
from ..transports.stats import clock_note, clocks
from .options import HttpAddress

__all__ = ["API_PATH", "HttpApi", "failure_text", "tls_context", "tls_hint"]

#: Every endpoint lives under this path (galileo-proto http.md).
API_PATH = "/api/v1"


def tls_context(address: HttpAddress) -> ssl.SSLContext | None:
    """The verifying TLS context of an https:// address (its ca_file, else the system's CAs)."""
    if not address.secure:
        return None
    return ssl.create_default_context(cafile=address.ca_file)


def tls_hint(exc: BaseException) -> str:
    """What to tell the user when ``exc`` is a refused server certificate, else ``""``."""
    if not isinstance(exc, aiohttp.ClientConnectorCertificateError):
        return ""
    return (
        f" (certificate verify failed: {exc.certificate_error.__class__.__name__}"
        f" {getattr(exc.certificate_error, 'verify_message', '')}; give ca_file= the CA's PEM file)"
    )


def _os_text(error: OSError) -> str:
    """The operating system's words for ``error`` ("Connection refused"), else its message."""
    if not isinstance(error, socket.gaierror) and error.errno is not None and error.errno > 0:
        return os.strerror(error.errno)
    return error.strerror or str(error) or type(error).__name__


def failure_text(exc: BaseException) -> str:
    """Why a request failed, with the address it tried and the OS's cause; never a URL's query.

    (A response error's own text would show the URL, token included: only its status is used.)
    """
    if isinstance(exc, aiohttp.ClientConnectorCertificateError):
        return f"cannot connect to {exc.host}:{exc.port}{tls_hint(exc)}"
    if isinstance(exc, aiohttp.ClientConnectorError):
        return f"cannot connect to {exc.host}:{exc.port} ({_os_text(exc.os_error)})"
    if isinstance(exc, aiohttp.ClientResponseError):
        return f"{type(exc).__name__} HTTP {exc.status}"
    if isinstance(exc, OSError):  # ClientOSError: a reset or broken connection
        return f"{type(exc).__name__} ({_os_text(exc)})"
    if isinstance(exc, aiohttp.ServerDisconnectedError):
        return "the server closed the connection without an answer"
    return type(exc).__name__


class HttpApi:
    """Calls endpoints, adds the token, and turns every failure into HttpError.

    The password and the token never appear in repr, logs or error messages: only the
    endpoint's path and the HTTP status do.
    """

    def __init__(
        self,
        base_url: str,
        *,
        username: str | None = None,
        password: SecretStr | None = None,
        token: SecretStr | None = None,
        timeout: float = 5.0,
        ssl_context: ssl.SSLContext | bool | None = None,
    ) -> None:
        self.base_url = base_url.rstrip("/")
        self.username = username
        self._password = password
        self.token = token
        self.timeout = timeout
        self._ssl: ssl.SSLContext | bool = True if ssl_context is None else ssl_context
        self._session: aiohttp.ClientSession | None = None
        self._closed = False

    def __repr__(self) -> str:
        return f"<HttpApi {self.base_url}>"

    @property
    def session(self) -> aiohttp.ClientSession:
        """The open session (created on first use, inside the running loop).

        ConnectionLost once close() was called.
        """
        if self._closed:
            raise ConnectionLost(f"{self.base_url}: the link is closed")
        if self._session is None or self._session.closed:
            self._session = aiohttp.ClientSession(
                timeout=aiohttp.ClientTimeout(total=self.timeout),
                connector=aiohttp.TCPConnector(ssl=self._ssl),
            )
        return self._session

    async def login(self) -> None:
        """Fetch a token (GET /token) with username and password, unless one is set or none."""
        if self.token is not None or self.username is None or self._password is None:
            return
        params = {"username": self.username, "password": self._password.get_secret_value()}
        answer = await self.call("GET", "/token", params, authenticate=False)
        token = answer.get("token") if isinstance(answer, dict) else None
        if not isinstance(token, str) or not token:
            raise AuthenticationError(
                f"GET {API_PATH}/token: no token in the answer (wrong username or password?)",
                endpoint="/token",
                status=None,
            )
        self.token = SecretStr(token)

    def refused_hint(self) -> str:
        """Why the robot answers 401: its token checking is on and the token is missing or stale."""
        if self.token is None:
            return " (the robot checks tokens: give token= or username and password)"
        return " (the robot refused the token: expired, revoked or wrong)"

    def token_query(self) -> dict[str, str]:
        """``{"token": …}`` when a token is known, else empty."""
        return {} if self.token is None else {"token": self.token.get_secret_value()}

    async def call(
        self,
        method: str,
        endpoint: str,
        params: dict[str, Any] | None = None,
        body: dict[str, Any] | None = None,
        *,
        authenticate: bool = True,
    ) -> Any:
        """The answer to ``method`` ``API_PATH + endpoint``: JSON, else text; an image as bytes.

        HttpError naming the endpoint: an HTTP status of 400 or more (``status``; 401:
        AuthenticationError), a failed connection (``status`` None, the OS's cause), or no
        answer within ``timeout`` (HttpTimeout, also a TimeoutError).
        """
        query = {k: str(v) for k, v in (params or {}).items()}
        if authenticate:
            query.update(self.token_query())
        where = f"{method} {API_PATH}{endpoint}"
        began = clocks()
        try:
            async with self.session.request(
                method, f"{self.base_url}{API_PATH}{endpoint}", params=query, json=body
            ) as response:
                binary = response.content_type.startswith("image/") or (
                    response.content_type == "application/octet-stream"
                )
                data: str | bytes = await (response.read() if binary else response.text())
                if response.status >= 400:
                    message = f"{where}: HTTP {response.status} {response.reason or ''}".rstrip()
                    if response.status == 401:
                        raise AuthenticationError(
                            message + self.refused_hint(), endpoint=endpoint, status=401
                        )
                    raise HttpError(message, endpoint=endpoint, status=response.status)
        except asyncio.TimeoutError:
            raise HttpTimeout(
                f"{where}: no answer within {self.timeout} s from {self.base_url} "
                f"(request_timeout){clock_note(began)}",
                endpoint=endpoint,
            ) from None
        except aiohttp.ClientError as exc:
            raise HttpError(
                f"{where}: {failure_text(exc)}", endpoint=endpoint, status=None
            ) from None
        if isinstance(data, bytes):
            return data
        try:
            return json.loads(data)
        except ValueError:
            return data

    async def close(self) -> None:
        """Close the session (idempotent)."""
        self._closed = True
        session, self._session = self._session, None
        if session is not None:
            await session.close()
