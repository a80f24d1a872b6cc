"""The control socket: where it is, what goes over it, and how another process asks.

A serial port is opened exclusively and a robot's UDP port streams to one reader, so a
second process cannot simply connect to a robot that another one drives. The owner (a
Robot connected with ``control_socket=True``) serves a Unix socket per port instead, in a
directory only this user may enter, and takes three operations there: stop, cancel, pause.

One JSON line each way. Request: ``{"op": "stop"|"cancel"|"pause", "brake"?: int,
"timeout"?: float, "from": {"pid": int, "argv": [str, …]}}``. Answer: ``{"ok": true,
"pid": int, "argv": [str, …], "done": str, …}`` or ``{"ok": false, "pid": …, "argv": …,
"error": type name, "message": str, …}``.
"""

from __future__ import annotations

import asyncio
import contextlib
import hashlib
import ipaddress
import json
import os
import shlex
import socket
import stat
import struct
import sys
import tempfile
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..errors import GalileoConnectionError, GalileoTimeout, InvalidArgument
from ..links import link_kind
from ..transports.udp import parse_udp_url
from .operations import DEFAULT_TIMEOUT
from .stopping import DEFAULT_STOP_TIMEOUT

__all__ = [
    "ANSWER_MARGIN",
    "CONTROL_OPERATIONS",
    "DIRECTORY_NAME",
    "MAX_LINE_BYTES",
    "ControlUnavailable",
    "NoOwner",
    "OwnerAnswer",
    "Peer",
    "ask_owner",
    "command_line",
    "control_key",
    "decode_line",
    "encode_line",
    "own_argv",
    "own_socket",
    "peer_credentials",
    "private_directory",
    "socket_path",
]

#: The only operations a control socket runs, with the owner's timeout when none is asked.
CONTROL_OPERATIONS: Mapping[str, float] = {
    "stop": DEFAULT_STOP_TIMEOUT,
    "cancel": DEFAULT_TIMEOUT,
    "pause": DEFAULT_TIMEOUT,
}
#: The directory's name under $XDG_RUNTIME_DIR (else ``galileo-async-<uid>`` in the temp dir).
DIRECTORY_NAME = "galileo-async"
#: Longest request or answer line, bytes.
MAX_LINE_BYTES = 65536
#: Seconds an asker waits for the answer beyond the operation's own timeout.
ANSWER_MARGIN = 5.0
#: Longest Unix socket path used (sun_path holds 104 bytes on macOS, 108 on Linux).
_MAX_SOCKET_PATH = 100
#: The asker's command line as sent: at most this many words of at most this many characters.
_MAX_WORDS, _MAX_WORD = 64, 512


class ControlUnavailable(Exception):
    """No control socket can be used here; the message says why (not a GalileoError)."""


class NoOwner(ControlUnavailable):
    """No process serves the control socket of the port (none there, or a stale one)."""


def control_key(url: str) -> str | None:
    """What names a port's control socket, or None for URLs that have none.

    Serial device paths (their real path: ``/dev/galileo`` and ``/dev/ttyUSB0`` meet) and
    ``udp://host:port``; pyserial URLs, ``socket://``, ``http://``, ``ros://`` and
    ``sim://`` have none, nor has a platform without Unix sockets.
    """
    if not hasattr(socket, "AF_UNIX") or sys.platform == "win32":
        return None
    kind = link_kind(url)
    if kind == "serial" and "://" not in url:
        return f"serial {os.path.realpath(url)}"
    if kind == "udp":
        host, port = parse_udp_url(url)
        with contextlib.suppress(ValueError):
            host = ipaddress.ip_address(host).compressed
        return f"udp {host.lower()}:{port}"
    return None


def _directories() -> list[Path]:
    """Where control sockets go, first choice first: $XDG_RUNTIME_DIR, then the temp dir."""
    found = []
    runtime = os.environ.get("XDG_RUNTIME_DIR")
    if runtime and os.path.isabs(runtime):
        found.append(Path(runtime) / DIRECTORY_NAME)
    found.append(Path(tempfile.gettempdir()) / f"{DIRECTORY_NAME}-{os.getuid()}")
    return found


def socket_path(key: str) -> Path:
    """The control socket of ``key`` (control_key): a hash of it in the first directory
    whose path is short enough for a Unix socket. Both sides compute it alike."""
    name = hashlib.sha256(key.encode("utf-8", "surrogateescape")).hexdigest()[:32] + ".sock"
    for directory in _directories():
        path = directory / name
        if len(os.fsencode(path)) <= _MAX_SOCKET_PATH:
            return path
    raise ControlUnavailable(f"{path}: too long for a Unix socket")


def private_directory(path: Path, *, create: bool) -> None:
    """ControlUnavailable unless ``path`` is a real directory of this user closed to others.

    ``create``: make it (mode 0700) when missing, else FileNotFoundError. A symlink, a
    directory of another user or one others may enter is refused, never repaired: someone
    else may have made it.
    """
    if create:
        try:
            os.mkdir(path, 0o700)
        except FileExistsError:
            pass
        except OSError as exc:
            raise ControlUnavailable(f"cannot create {path}: {exc.strerror or exc}") from None
    try:
        info = os.lstat(path)
    except FileNotFoundError:
        raise
    except OSError as exc:
        raise ControlUnavailable(f"{path}: {exc.strerror or exc}") from None
    if not stat.S_ISDIR(info.st_mode):
        raise ControlUnavailable(f"{path} is not a directory (a symlink?): not used")
    if info.st_uid != os.getuid():
        raise ControlUnavailable(f"{path} belongs to uid {info.st_uid}, not to this user")
    if info.st_mode & 0o077:
        mode = stat.S_IMODE(info.st_mode)
        raise ControlUnavailable(f"{path} is open to other users (mode {mode:04o}, not 0700)")


def own_socket(path: Path) -> os.stat_result:
    """The lstat of ``path``; ControlUnavailable unless it is a socket of this user."""
    info = os.lstat(path)
    if not stat.S_ISSOCK(info.st_mode) or info.st_uid != os.getuid():
        raise ControlUnavailable(f"{path} is not a socket of this user: not used")
    return info


@dataclass(frozen=True)
class Peer:
    """The process at the other end of a Unix socket, as the kernel tells (None: unknown)."""

    pid: int | None = None
    uid: int | None = None
    gid: int | None = None


_UCRED = struct.Struct("3i")


def peer_credentials(sock: Any) -> Peer:
    """The peer of a connected Unix socket: SO_PEERCRED on Linux; unknown elsewhere."""
    option = getattr(socket, "SO_PEERCRED", None)
    if option is None or sock is None:
        return Peer()
    try:
        pid, uid, gid = _UCRED.unpack(sock.getsockopt(socket.SOL_SOCKET, option, _UCRED.size))
    except OSError:
        return Peer()
    return Peer(pid, uid, gid)


def command_line(pid: int | None, fallback: object = None) -> str:
    """Process ``pid``'s command line (/proc on Linux), else ``fallback`` (a claimed argv).

    One printable line: control characters show escaped, so no one writes log lines.
    """
    words: list[str] | None = None
    if pid is not None:
        with contextlib.suppress(OSError):
            raw = Path(f"/proc/{pid}/cmdline").read_bytes()
            words = [os.fsdecode(part) for part in raw.rstrip(b"\0").split(b"\0")] if raw else None
    if words is None and isinstance(fallback, list):
        words = [str(part) for part in fallback]
    if not words:
        return "?"
    line = shlex.join(words)
    return "".join(ch if ch.isprintable() else ascii(ch)[1:-1] for ch in line)


def own_argv() -> list[str]:
    """This process's command line as sent: the first words, each cut short (lines stay short)."""
    return [word[:_MAX_WORD] for word in sys.argv[:_MAX_WORDS]]


def encode_line(message: Mapping[str, Any]) -> bytes:
    """One JSON line."""
    return json.dumps(message, separators=(",", ":")).encode() + b"\n"


def decode_line(line: bytes) -> dict[str, Any]:
    """The JSON object of one line; ValueError for anything else."""
    message = json.loads(line)
    if not isinstance(message, dict):
        raise ValueError(f"expected a JSON object, got {type(message).__name__}")
    return message


@dataclass(frozen=True)
class OwnerAnswer:
    """What the process owning a port answered: its ``pid``, its ``command`` line, the fields."""

    pid: int | None
    command: str
    fields: Mapping[str, Any]

    @property
    def ok(self) -> bool:
        """True when the operation returned in the owner."""
        return self.fields.get("ok") is True

    @property
    def done(self) -> str:
        """What was done, in words (ok answers)."""
        return str(self.fields.get("done", ""))

    @property
    def error(self) -> str:
        """The type name of the owner's error (failed answers)."""
        return str(self.fields.get("error", "GalileoError"))

    @property
    def message(self) -> str:
        """The owner's error message (failed answers)."""
        return str(self.fields.get("message", ""))


async def ask_owner(
    url: str, op: str, *, brake: int | None = None, timeout: float | None = None
) -> OwnerAnswer:
    """Ask the process that owns ``url``'s port to run ``op``; its answer.

    NoOwner when nobody serves the port's control socket (none, or a stale one: the
    caller may open the port itself); ControlUnavailable when the directory is not
    private; GalileoTimeout when the owner does not answer within ``timeout`` (the
    operation's, None: the owner's default) plus ANSWER_MARGIN s; GalileoConnectionError
    when it closes without answering. Cancelling the call closes the connection.
    """
    if op not in CONTROL_OPERATIONS:
        raise InvalidArgument(f"op must be one of {', '.join(CONTROL_OPERATIONS)}, got {op!r}")
    key = control_key(url)
    if key is None:
        raise NoOwner(f"{url}: this kind of port has no control socket")
    path = socket_path(key)
    try:
        private_directory(path.parent, create=False)
        own_socket(path)
    except FileNotFoundError:
        raise NoOwner(f"no process serves a control socket for {url}") from None
    try:
        reader, writer = await asyncio.open_unix_connection(os.fspath(path), limit=MAX_LINE_BYTES)
    except (ConnectionRefusedError, FileNotFoundError):
        raise NoOwner(f"no process serves a control socket for {url} (a stale one)") from None
    try:
        owner = peer_credentials(writer.get_extra_info("socket"))
        request: dict[str, Any] = {"op": op, "from": {"pid": os.getpid(), "argv": own_argv()}}
        if brake is not None:
            request["brake"] = brake
        if timeout is not None:
            request["timeout"] = timeout
        writer.write(encode_line(request))
        wait = (CONTROL_OPERATIONS[op] if timeout is None else timeout) + ANSWER_MARGIN
        return await _answer(reader, url, op, owner, wait)
    finally:
        writer.close()  # the socket closes on the loop's next turn, cancelled or not


async def _answer(
    reader: asyncio.StreamReader, url: str, op: str, owner: Peer, wait: float
) -> OwnerAnswer:
    who = f"the process that owns {url}" + (f" (pid {owner.pid})" if owner.pid else "")
    try:
        line = await asyncio.wait_for(reader.readline(), wait)
    except asyncio.TimeoutError:
        raise GalileoTimeout(
            f"{who} did not answer {op} within {wait:g} s: its event loop may be blocked; "
            "it may still run it later, and nothing confirms the robot stopped"
        ) from None
    except (ConnectionError, ValueError) as exc:  # ValueError: a line over the limit
        raise GalileoConnectionError(f"{who}: no answer to {op}: {exc}") from None
    if not line:
        raise GalileoConnectionError(f"{who} closed the control socket without answering {op}")
    try:
        fields = decode_line(line)
    except ValueError as exc:
        raise GalileoConnectionError(f"{who} answered {op} with a bad line: {exc}") from None
    pid = fields.get("pid")
    pid = pid if isinstance(pid, int) else owner.pid
    return OwnerAnswer(pid, command_line(pid, fields.get("argv")), fields)
