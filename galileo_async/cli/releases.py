"""``--release NAME=…``: what releases a mission's ``wait`` steps on the command line.

``key`` (Enter on stdin), ``file:PATH`` (PATH appears), ``http:[HOST:]PORT`` (``POST
/release/NAME`` to a small HTTP server, extra [http]) and ``mqtt:mqtt://HOST[:PORT]/TOPIC``
(any message on TOPIC, extra [vda5050]). A trigger given before its wait starts is
remembered once.
"""

from __future__ import annotations

import asyncio
import contextlib
import sys
from collections.abc import AsyncIterator, Awaitable, Callable
from dataclasses import dataclass
from pathlib import Path
from urllib.parse import urlsplit

import anyio
import anyio.abc
import anyio.to_thread

from ..robot.runtime import finish_shielded

if sys.version_info < (3, 11):
    from exceptiongroup import BaseExceptionGroup  # type: ignore[import-not-found]

from .output import err_console
from .runner import ExitCode, fail

__all__ = [
    "DEFAULT_HOST",
    "FILE_RELEASE_PERIOD",
    "MQTT_PORT",
    "HttpTrigger",
    "MqttTrigger",
    "Release",
    "Releases",
    "parse_releases",
    "triggered",
]

#: Seconds between two looks for the file of a ``file:PATH`` release.
FILE_RELEASE_PERIOD = 0.5
#: The host an ``http:PORT`` release serves on.
DEFAULT_HOST = "127.0.0.1"
#: The port of an ``mqtt://HOST/TOPIC`` broker without one.
MQTT_PORT = 1883

Release = Callable[[], Awaitable[object]]
USAGE = "give NAME=key, NAME=file:PATH, NAME=http:[HOST:]PORT or NAME=mqtt:mqtt://HOST[:PORT]/TOPIC"


@dataclass(frozen=True)
class HttpTrigger:
    """``POST /release/NAME`` on the server at host:port releases NAME."""

    host: str
    port: int


@dataclass(frozen=True)
class MqttTrigger:
    """Any message on ``topic`` of the broker at host:port releases NAME."""

    host: str
    port: int
    topic: str


Releases = dict[str, Release | HttpTrigger | MqttTrigger]


def parse_releases(specs: list[str] | None) -> Releases:
    """The ``--release`` specs by name; exit 2 naming a bad spec or a missing extra."""
    releases: Releases = {}
    for spec in specs or []:
        name, _, how = spec.partition("=")
        if not name or not how:
            fail(f"--release {spec!r}: {USAGE}", ExitCode.USAGE)
        if how == "key":
            releases[name] = _key
        elif how.startswith("file:") and how[5:]:
            releases[name] = _file_release(Path(how[5:]))
        elif how.startswith("http:"):
            releases[name] = _http_trigger(spec, how[5:])
        elif how.startswith("mqtt:"):
            releases[name] = _mqtt_trigger(spec, how[5:])
        else:
            fail(f"--release {spec!r}: {USAGE}", ExitCode.USAGE)
    return releases


def _port(spec: str, text: str) -> int:
    if not text.isdigit() or not 0 < int(text) < 65536:
        fail(f"--release {spec!r}: {text!r} is not a port (1 to 65535)", ExitCode.USAGE)
    return int(text)


def _http_trigger(spec: str, where: str) -> HttpTrigger:
    host, _, port = where.rpartition(":")
    try:
        import aiohttp.web  # noqa: F401
    except ImportError:
        fail(f"--release {spec!r} needs aiohttp: pip install 'galileo-async[http]'",
             ExitCode.USAGE)  # fmt: skip
    return HttpTrigger(host.strip("[]") or DEFAULT_HOST, _port(spec, port))


def _mqtt_trigger(spec: str, url: str) -> MqttTrigger:
    parts = urlsplit(url)
    topic = parts.path[1:]
    try:
        port = parts.port or MQTT_PORT
    except ValueError:
        fail(f"--release {spec!r}: {url!r} has a bad port", ExitCode.USAGE)
    if parts.scheme != "mqtt" or not parts.hostname or not topic:
        fail(f"--release {spec!r}: give mqtt:mqtt://HOST[:PORT]/TOPIC", ExitCode.USAGE)
    try:
        import aiomqtt  # noqa: F401
    except ImportError:
        fail(f"--release {spec!r} needs aiomqtt: pip install 'galileo-async[vda5050]'",
             ExitCode.USAGE)  # fmt: skip
    return MqttTrigger(parts.hostname, port, topic)


async def _key() -> None:
    await anyio.to_thread.run_sync(sys.stdin.readline, abandon_on_cancel=True)


def _file_release(path: Path) -> Release:
    async def appears() -> None:
        # A file's appearance has no event to await without inotify: look now and then.
        while not await anyio.Path(path).exists():  # noqa: ASYNC110
            await anyio.sleep(FILE_RELEASE_PERIOD)

    return appears


class _Latch:
    """A trigger remembered until one wait takes it."""

    def __init__(self) -> None:
        self._given = anyio.Event()

    def give(self) -> None:
        """Release the next (or current) wait; several gives before it count as one."""
        self._given.set()

    async def take(self) -> None:
        """Return once given, and forget it (every wait taking it then is released)."""
        given = self._given
        await given.wait()
        if self._given is given:
            self._given = anyio.Event()


@contextlib.asynccontextmanager
async def triggered(releases: Releases) -> AsyncIterator[dict[str, Release]]:
    """The releases of ``run_mission``, their HTTP servers serving and MQTT clients
    subscribed (one per host:port) until exit, whatever the exit."""
    latches = {name: _Latch() for name, how in releases.items() if not callable(how)}
    ready: dict[str, Release] = {
        name: how if callable(how) else latches[name].take for name, how in releases.items()
    }
    servers: dict[tuple[str, int], dict[str, _Latch]] = {}
    brokers: dict[tuple[str, int], dict[str, list[_Latch]]] = {}
    for name, how in releases.items():
        if isinstance(how, HttpTrigger):
            servers.setdefault((how.host, how.port), {})[name] = latches[name]
        elif isinstance(how, MqttTrigger):
            topics = brokers.setdefault((how.host, how.port), {})
            topics.setdefault(how.topic, []).append(latches[name])
    try:
        async with contextlib.AsyncExitStack() as stack:
            for (host, port), named in servers.items():
                await stack.enter_async_context(_served(host, port, named))
            group = await stack.enter_async_context(anyio.create_task_group())
            stack.callback(group.cancel_scope.cancel)
            for (host, port), topics in brokers.items():
                await group.start(_subscribed, host, port, topics)
            yield ready
    except BaseExceptionGroup as errors:
        # The command maps an error's type to its exit code: one error leaves as itself.
        if len(errors.exceptions) != 1:
            raise
        raise errors.exceptions[0] from None


@contextlib.asynccontextmanager
async def _served(host: str, port: int, latches: dict[str, _Latch]) -> AsyncIterator[None]:
    from aiohttp import web

    async def release(request: web.Request) -> web.Response:
        name = request.match_info["name"]
        if name not in latches:
            return web.json_response({"error": f"no release {name!r} here"}, status=404)
        latches[name].give()
        return web.json_response({"released": name})

    app = web.Application()
    app.router.add_post("/release/{name}", release)
    runner = web.AppRunner(app, access_log=None)
    await runner.setup()
    try:
        await web.TCPSite(runner, host, port).start()
        for name in latches:
            err_console().print(f"release {name}: POST http://{host}:{port}/release/{name}",
                                markup=False, highlight=False)  # fmt: skip
        yield
    finally:
        # Shielded: a cancelled block (Ctrl-C, a failing sibling) must not leave it listening.
        await finish_shielded(asyncio.ensure_future(runner.cleanup()), "the release server")


async def _subscribed(
    host: str,
    port: int,
    topics: dict[str, list[_Latch]],
    *,
    task_status: anyio.abc.TaskStatus[None] = anyio.TASK_STATUS_IGNORED,
) -> None:
    import aiomqtt

    async with aiomqtt.Client(host, port) as client:
        for topic in topics:
            await client.subscribe(topic, qos=1)
        for topic in topics:
            err_console().print(f"release on mqtt://{host}:{port}/{topic}",
                                markup=False, highlight=False)  # fmt: skip
        task_status.started()
        async for message in client.messages:
            for topic, latches in topics.items():
                if message.topic.matches(topic):
                    for latch in latches:
                        latch.give()
