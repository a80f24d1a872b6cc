"""The owner's end of the control socket (robot/control.py): a small server on the Robot's loop.

It runs stop, cancel and pause through the same Robot methods as every other caller, and
nothing else; it refuses other users' processes (SO_PEERCRED, where the kernel tells) and
logs who asked at WARNING (logger ``galileo_async.robot.control_server``).
"""

from __future__ import annotations

import asyncio
import contextlib
import errno
import logging
import math
import os
import socket
from collections.abc import Awaitable, Callable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..errors import InvalidArgument
from .control import (
    CONTROL_OPERATIONS,
    MAX_LINE_BYTES,
    ControlUnavailable,
    Peer,
    command_line,
    control_key,
    decode_line,
    encode_line,
    own_argv,
    own_socket,
    peer_credentials,
    private_directory,
    socket_path,
)

if TYPE_CHECKING:
    from .robot import Robot

__all__ = [
    "CLOSE_GRACE",
    "CLOSE_TIMEOUT",
    "MAX_ASKED_TIMEOUT",
    "PROBE_TIMEOUT",
    "REQUEST_TIMEOUT",
    "ControlOperation",
    "ControlServer",
    "asked_timeout",
    "control_operations",
    "serve_control",
]

_log = logging.getLogger(__name__)

#: An operation the server runs: the request in, the answer's fields out.
ControlOperation = Callable[[Mapping[str, Any]], Awaitable[dict[str, Any]]]
#: How the server learns who is at the other end of a connection (a socket in, a Peer out).
Credentials = Callable[[Any], Peer]

#: Seconds a connected process has to send its request line.
REQUEST_TIMEOUT = 5.0
#: Seconds to tell a live owner of an existing socket file from a stale one.
PROBE_TIMEOUT = 1.0
#: Longest close() lets running requests finish and answer (a stop asked here may be what
#: ended the owner's program: its confirmation still comes over the open link).
CLOSE_GRACE = 3.0
#: Longest close() then waits for cancelled requests and connections to end.
CLOSE_TIMEOUT = 2.0
#: Longest timeout an asker may set for an operation, seconds.
MAX_ASKED_TIMEOUT = 60.0
_BACKLOG = 8


def asked_timeout(request: Mapping[str, Any], default: float) -> float:
    """The request's ``timeout`` (above 0, at most MAX_ASKED_TIMEOUT s), else ``default``."""
    value = request.get("timeout", default)
    if (
        isinstance(value, bool)
        or not isinstance(value, (int, float))
        or not 0 < value <= MAX_ASKED_TIMEOUT
        or not math.isfinite(value)
    ):
        raise InvalidArgument(f"timeout must be above 0 and at most {MAX_ASKED_TIMEOUT:g} s")
    return float(value)


def control_operations(robot: Robot) -> dict[str, ControlOperation]:
    """stop, cancel and pause of ``robot``, as the control socket (and ``galileo``) run them.

    Each takes a request (``brake``, ``timeout``) and gives the answer's fields: ``done``
    in words, and ``stopped`` (stop) or ``goal_was_running`` (cancel).
    """

    async def stop(request: Mapping[str, Any]) -> dict[str, Any]:
        timeout = asked_timeout(request, CONTROL_OPERATIONS["stop"])
        report = await robot.stop(request.get("brake", 100), timeout=timeout)
        return {"done": str(report), "stopped": list(report.stopped)}

    async def cancel(request: Mapping[str, Any]) -> dict[str, Any]:
        timeout = asked_timeout(request, CONTROL_OPERATIONS["cancel"])
        status = robot.status
        running = status is None or status.goal_active  # unknown: assume one ran
        await robot.cancel(timeout=timeout)
        done = "goal cancelled" if running else "no goal was running"
        return {"done": done, "goal_was_running": running}

    async def pause(request: Mapping[str, Any]) -> dict[str, Any]:
        await robot.pause(timeout=asked_timeout(request, CONTROL_OPERATIONS["pause"]))
        return {"done": "goal paused"}

    return {"stop": stop, "cancel": cancel, "pause": pause}


async def serve_control(
    url: str,
    operations: Mapping[str, ControlOperation],
    *,
    credentials: Credentials = peer_credentials,
) -> ControlServer | None:
    """Serve ``operations`` on the control socket of ``url``'s port until close().

    None when the port has none (control_key), or when it cannot be served: the
    directory is not private, or another live process serves it (a WARNING says why).
    A stale socket file (its process ended without removing it) is replaced.
    """
    key = control_key(url)
    if key is None:
        _log.debug("%s: this kind of port has no control socket", url)
        return None
    try:
        path = socket_path(key)
        private_directory(path.parent, create=True)
        sock = await _bound(path, url)
    except ControlUnavailable as exc:
        _log.warning("%s: no control socket: %s", url, exc)
        return None
    server = ControlServer(url, path, sock, operations, credentials)
    try:
        await server.listen()
    except BaseException:
        await server.close()
        raise
    _log.debug("%s: control socket %s", url, path)
    return server


async def _bound(path: Path, url: str) -> socket.socket:
    """A listening socket bound at ``path``, once a stale file there is replaced."""
    for _ in range(2):
        try:
            return _bind(path)
        except OSError as exc:
            if exc.errno != errno.EADDRINUSE:
                raise ControlUnavailable(f"cannot bind {path}: {exc.strerror or exc}") from None
        await _replace_stale(path, url)
    raise ControlUnavailable(f"{path}: another process took it meanwhile")


def _bind(path: Path) -> socket.socket:
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    try:
        sock.bind(os.fspath(path))
        try:
            os.chmod(path, 0o600)  # the 0700 directory keeps others out; this is a second fence
            sock.listen(_BACKLOG)
        except BaseException:
            os.unlink(path)
            raise
    except BaseException:
        sock.close()
        raise
    return sock


async def _replace_stale(path: Path, url: str) -> None:
    """Remove the socket file at ``path`` when no process listens on it any more."""
    try:
        own_socket(path)
    except FileNotFoundError:
        return  # gone meanwhile: bind again
    owner = await _probe(path)
    if owner is not None:
        pid = f"process {owner.pid}" if owner.pid else "another process"
        raise ControlUnavailable(f"{pid} serves {path} already (it has {url} open too)")
    with contextlib.suppress(FileNotFoundError):
        os.unlink(path)
    _log.info("%s: replaced a stale control socket (its process ended without removing it)", url)


async def _probe(path: Path) -> Peer | None:
    """The process listening at ``path``, or None when the connection is refused."""
    try:
        _reader, writer = await asyncio.wait_for(
            asyncio.open_unix_connection(os.fspath(path)), PROBE_TIMEOUT
        )
    except (ConnectionRefusedError, FileNotFoundError):
        return None
    except asyncio.TimeoutError:
        return Peer()  # someone is there, slow to accept: leave it alone
    peer = peer_credentials(writer.get_extra_info("socket"))
    writer.close()
    return peer


class ControlServer:
    """The control socket of one port: serves stop, cancel and pause until close()."""

    def __init__(
        self,
        what: str,
        path: Path,
        sock: socket.socket,
        operations: Mapping[str, ControlOperation],
        credentials: Credentials,
    ) -> None:
        self.what = what
        self.path = path
        self._sock = sock
        info = os.lstat(path)
        self._identity = (info.st_dev, info.st_ino)  # removed on close only while it is ours
        self._operations = {op: operations[op] for op in CONTROL_OPERATIONS}
        self._credentials = credentials
        self._server: asyncio.AbstractServer | None = None
        self._requests: set[_Request] = set()
        self._tasks: set[asyncio.Task[None]] = set()
        self.closed = False

    async def listen(self) -> None:
        """Start taking connections on the Robot's loop."""
        loop = asyncio.get_running_loop()
        self._server = await loop.create_unix_server(lambda: _Request(self), sock=self._sock)

    async def close(self) -> None:
        """Stop listening, remove the socket file, let running requests finish (CLOSE_GRACE s),
        then end them; idempotent, bounded."""
        if self.closed:
            return
        self.closed = True
        if self._server is not None:
            self._server.close()
        else:
            self._sock.close()
        with contextlib.suppress(OSError):
            info = os.lstat(self.path)
            if (info.st_dev, info.st_ino) == self._identity:
                os.unlink(self.path)
        if self._tasks:
            await asyncio.wait(list(self._tasks), timeout=CLOSE_GRACE)
        tasks = list(self._tasks)
        for task in tasks:
            task.cancel()  # each answers that the owner closed meanwhile
        if tasks:
            await asyncio.wait(tasks, timeout=CLOSE_TIMEOUT)
        requests = list(self._requests)
        for request in requests:
            request.close()
        if requests:
            await asyncio.wait([request.lost for request in requests], timeout=CLOSE_TIMEOUT)

    def refusal(self, peer: Peer) -> dict[str, Any] | None:
        """The answer refusing ``peer``, a process of another user; None for this user's."""
        if peer.uid is None or peer.uid == os.getuid():
            return None
        _log.warning(
            "%s: refused process %s of uid %s: only this user's processes may ask",
            self.what, peer.pid, peer.uid,
        )  # fmt: skip
        return self.failure(
            "PermissionError", "only processes of the user that owns the port may ask"
        )

    def failure(self, error: str, message: str) -> dict[str, Any]:
        """A failed answer: the error's type name and message."""
        return {"ok": False, **self._identity_fields(), "error": error, "message": message}

    def start(self, request: _Request, line: bytes) -> None:
        """Run the request ``line`` of ``request`` in a task of its own; it answers."""
        task = asyncio.get_running_loop().create_task(
            self._run(request, line), name=f"control socket {self.what}"
        )
        self._tasks.add(task)
        task.add_done_callback(self._tasks.discard)

    async def _run(self, request: _Request, line: bytes) -> None:
        try:
            answer = await self._answer(request.peer, line)
        except asyncio.CancelledError:
            request.answer(
                self.failure("ConnectionLost", f"{self.what} was closed before the operation ended")
            )
            raise
        request.answer(answer)

    async def _answer(self, peer: Peer, line: bytes) -> dict[str, Any]:
        try:
            message = decode_line(line)
            op = message.get("op")
            if op not in self._operations:
                raise ValueError(f"op {op!r} is not one of {', '.join(CONTROL_OPERATIONS)}")
        except ValueError as exc:
            _log.warning("%s: refused a request of process %s: %s", self.what, peer.pid, exc)
            return self.failure("InvalidArgument", f"not a control request: {exc}")
        claimed = message.get("from")
        argv = claimed.get("argv") if isinstance(claimed, dict) else None
        asked = f"{op} (brake {message['brake']})" if "brake" in message else op
        _log.warning(
            "%s: %s asked through the control socket by process %s (uid %s): %s",
            self.what, asked, peer.pid if peer.pid is not None else "?",
            peer.uid if peer.uid is not None else "?", command_line(peer.pid, argv),
        )  # fmt: skip
        try:
            fields = await self._operations[op](message)
        except Exception as exc:  # the operation's outcome, answered to the asker
            answer = self.failure(type(exc).__name__, str(exc) or type(exc).__name__)
            unconfirmed = getattr(exc, "unconfirmed", None)
            if isinstance(unconfirmed, tuple):
                answer["unconfirmed"] = list(unconfirmed)
            _log.warning("%s: %s for process %s failed: %s", self.what, op, peer.pid, exc)
            return answer
        return {"ok": True, **self._identity_fields(), **fields}

    @staticmethod
    def _identity_fields() -> dict[str, Any]:
        return {"pid": os.getpid(), "argv": own_argv()}


class _Request(asyncio.Protocol):
    """One connection: the asker's credentials, one request line in, one answer out, closed."""

    def __init__(self, server: ControlServer) -> None:
        self._server = server
        self._buffer = bytearray()
        self._transport: asyncio.BaseTransport | None = None
        self._timer: asyncio.TimerHandle | None = None
        self._started = False
        self.peer = Peer()
        #: Done once the connection is closed.
        self.lost: asyncio.Future[None] = asyncio.get_running_loop().create_future()

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        self._transport = transport
        server = self._server
        server._requests.add(self)
        if server.closed:
            transport.close()
            return
        self.peer = server._credentials(transport.get_extra_info("socket"))
        refusal = server.refusal(self.peer)
        if refusal is not None:
            self._started = True
            self.answer(refusal)
            return
        self._timer = asyncio.get_running_loop().call_later(REQUEST_TIMEOUT, transport.close)

    def data_received(self, data: bytes) -> None:
        if self._started:
            return  # one request per connection
        self._buffer += data
        line, newline, _rest = self._buffer.partition(b"\n")
        if newline:
            self._started = True
            self._stop_timer()
            self._server.start(self, bytes(line))
        elif len(self._buffer) > MAX_LINE_BYTES:
            self._started = True
            self.answer(self._server.failure("InvalidArgument", "the request line is too long"))

    def eof_received(self) -> bool:
        return self._started  # keep the connection open to answer a request already read

    def connection_lost(self, exc: Exception | None) -> None:
        self._stop_timer()
        self._server._requests.discard(self)
        if not self.lost.done():
            self.lost.set_result(None)

    def answer(self, message: Mapping[str, Any]) -> None:
        """Write ``message`` as the answer line and close (nothing once closed)."""
        transport = self._transport
        if isinstance(transport, asyncio.WriteTransport) and not transport.is_closing():
            transport.write(encode_line(message))
            transport.close()

    def close(self) -> None:
        """Close the connection (what was written still goes out)."""
        if self._transport is not None:
            self._transport.close()

    def _stop_timer(self) -> None:
        if self._timer is not None:
            self._timer.cancel()
            self._timer = None
