"""connect(): URL → transport → status store → Robot, opened and waiting for the first status."""

from __future__ import annotations

import asyncio
import logging
import sys
from collections.abc import Generator
from types import TracebackType
from typing import TYPE_CHECKING, Any

from .._checks import hide_secrets
from ..errors import ConnectionLost, GalileoConnectionError, GalileoTimeout, InvalidArgument
from ..links import open_link
from ..options import FIRST_STATUS_TIMEOUT, OPTIONS, ConnectOptions, options_checked
from ..state.store import StatusStore
from ..transitions import DEFAULT_ARRIVE_TOLERANCE
from ..transports import clock_note, clocks, loop_clock
from .control_server import control_operations, serve_control
from .options import check_connect_options
from .robot import Robot
from .runtime import finish_shielded, running_loop

if TYPE_CHECKING:  # annotations only: no runtime dependency on typing_extensions
    if sys.version_info >= (3, 11):
        from typing import Unpack
    else:
        from typing_extensions import Unpack

__all__ = ["FIRST_STATUS_TIMEOUT", "Connection", "connect"]

_log = logging.getLogger(__name__)


class Connection:
    """What connect() returns: ``await`` it for a Robot, or use it as ``async with``."""

    def __init__(self, url: str, options: ConnectOptions | dict[str, Any]) -> None:
        if not isinstance(url, str) or not url:
            raise InvalidArgument(f"url must be a non-empty string, got {url!r}")
        check_connect_options(url, options)
        self.url = url
        self._options: dict[str, Any] = dict(options)
        self._robot: Robot | None = None

    def __await__(self) -> Generator[Any, None, Robot]:
        return self._open().__await__()

    async def __aenter__(self) -> Robot:
        self._robot = await self._open()
        return self._robot

    async def __aexit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        if self._robot is not None:
            await self._robot.close()

    async def _open(self) -> Robot:
        shown = hide_secrets(self.url)  # a password or token in the URL is never logged
        running_loop(f"connect({shown!r})")
        options = dict(self._options)
        robot_options = {n: options.pop(n) for n in list(options) if _owner(n) == "robot"}
        first_status_timeout = options.pop("first_status_timeout", FIRST_STATUS_TIMEOUT)
        control_socket = options.pop("control_socket", False)
        store = StatusStore(
            arrive_tolerance=robot_options.get("arrive_tolerance", DEFAULT_ARRIVE_TOLERANCE),
            clock=loop_clock(),
        )
        with options_checked():  # by __init__, once
            link = open_link(self.url, store, **options)
        try:
            with options_checked():
                robot = Robot(link, store, **robot_options)
        except BaseException:
            closing = asyncio.get_running_loop().create_task(link.close())
            await finish_shielded(closing, "closing the link")
            raise
        try:
            await link.open()
            count = link.map_target_count()  # sim:// and ros:// can tell
            robot._targets.link_count = count
            if "map_targets" not in robot_options:
                robot.map_targets = count
            if first_status_timeout is not None:
                await _first_status(store, first_status_timeout, shown)
            if control_socket:
                server = await serve_control(self.url, control_operations(robot))
                if server is not None:  # closed first when the Robot closes
                    robot._closers.append(server.close)
        except BaseException:
            await robot.close()
            raise
        _log.debug("connected to %s", shown)
        return robot


def _owner(name: str) -> str:
    """Who takes option ``name``; a scheme's own option (a plugin's) is its link's."""
    option = OPTIONS.get(name)
    return "link" if option is None else option.owner


async def _first_status(store: StatusStore, timeout: float, url: str) -> None:
    began = clocks()
    try:
        await store.first_frame(timeout)
    except GalileoTimeout:
        dropped = store.link_error
        why = f"; last: {dropped}" if isinstance(dropped, ConnectionLost) else ""
        raise GalileoConnectionError(
            f"connected to {url}, but no valid status frame arrived within {timeout} s"
            f"{clock_note(began)} (wrong port, baud rate or device?){why}"
        ) from None
    except ConnectionLost as exc:  # the link ended (no reconnect): say why
        raise ConnectionLost(f"{url}: dropped before the first status frame: {exc}") from exc


def connect(url: str, **options: Unpack[ConnectOptions]) -> Connection:
    """Connect to the robot at ``url``: ``async with connect(url) as robot`` or ``await``.

    ``url``: a serial device path, ``socket://host:port``, ``udp://host[:port]``, ``sim://…``
    or ``ros://…``. ``options``: those of galileo_async.options.ConnectOptions (OPTIONS
    describes each: type, default, which link kinds take it). All are checked here, once,
    before anything opens (InvalidArgument naming one); connecting needs a running asyncio
    loop (AsyncioRequired otherwise).
    """
    return Connection(url, options)
