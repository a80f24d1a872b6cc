"""Bad options and arguments: InvalidArgument naming them, before anything is opened or sent.

Options are checked by connect() itself, so the error comes from the call, before a
coroutine could open anything; the listening peer also shows no accepted connection.
Method arguments are checked before a command is queued: a marker command sent after
them is the first and only one the fake robot receives.
"""

from __future__ import annotations

import asyncio
import contextlib
import math
import os
import socket
from collections.abc import AsyncIterator, Awaitable, Callable, Iterator
from typing import Any

import anyio
import pytest

import galileo_async as galileo
from galileo_async import AsyncioRequired, GalileoConnectionError, InvalidArgument, ros, transports
from galileo_async.protocol import Stop
from galileo_async.robot.options import CONNECT_OPTIONS
from galileo_async.robot.runtime import running_loop
from tests.support.ports import refused_port
from tests.support.scripted_robot import connected, nothing_was_sent_before_marker

#: What a careless caller passes: not finite, beyond float range, negative, a str, a bool.
BAD_VALUES: tuple[Any, ...] = (math.nan, math.inf, -math.inf, 10**400, -1, 0, "1", True)

ROBOT_OPTIONS = (
    "map_targets", "accept_timeout", "arrive_tolerance", "goal_timeout", "wait_timeout",
    "first_status_timeout", "progress_timeout", "angle_tolerance",
    "max_linear_speed", "max_angular_speed",
    "first_status_timeout", "control_socket",
)  # fmt: skip
LINK_OPTIONS = (
    "reconnect", "reconnect_initial", "reconnect_max", "stale_timeout", "stale_reconnect",
    "min_command_interval", "drain_timeout", "max_queued_commands",
)  # fmt: skip
STREAM_OPTIONS = ("layout", "baudrate", "serial_options", "connect_timeout")
ROS_OPTIONS = ("host", "bind", "node_name", "connect_timeout", "rpc_timeout", "hosts",
               "master_check_interval", "layout", "baudrate", "serial_options")  # fmt: skip
#: Values among BAD_VALUES that an option does take.
ACCEPTED: dict[str, tuple[Any, ...]] = {
    "reconnect": (True,),
    "control_socket": (True,),
    "map_targets": (0,),
    "arrive_tolerance": (0,),
    "angle_tolerance": (0,),
    "min_command_interval": (0,),
    "host": ("1",),
    "bind": ("1",),
    "node_name": ("1",),
}


def bad_values(name: str) -> list[Any]:
    """The values of BAD_VALUES that ``name`` must refuse."""
    accepted = ACCEPTED.get(name, ())
    return [v for v in BAD_VALUES if not any(v is a or v == a for a in accepted)]


def option_cases(kind: str, names: tuple[str, ...]) -> list[Any]:
    return [
        pytest.param(kind, name, value, id=f"{kind}-{name}={value!r}")
        for name in names
        for value in bad_values(name)
    ]


class Listener:
    """A loopback TCP server that only counts the connections it accepts."""

    def __init__(self) -> None:
        self.accepted = 0
        self.port = 0
        self._server: asyncio.Server | None = None

    async def __aenter__(self) -> Listener:
        self._server = await asyncio.start_server(self._accept, "127.0.0.1", 0)
        self.port = self._server.sockets[0].getsockname()[1]
        return self

    async def __aexit__(self, *exc_info: object) -> None:
        assert self._server is not None
        self._server.close()
        await self._server.wait_closed()

    async def _accept(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        self.accepted += 1
        writer.close()


@contextlib.contextmanager
def pty_path() -> Iterator[str]:
    """The device path of a pty's far end (a serial port nothing answers on)."""
    controller, device = os.openpty()
    try:
        yield os.ttyname(device)
    finally:
        os.close(controller)
        os.close(device)


@contextlib.asynccontextmanager
async def url_of(kind: str) -> AsyncIterator[tuple[str, Listener | None]]:
    """A URL of link ``kind`` and, for TCP kinds, the listener behind it."""
    if kind == "serial":
        with pty_path() as path:
            yield path, None
    elif kind == "sim":
        yield "sim://?speed=20", None
    else:
        async with Listener() as listener:
            scheme = "ros" if kind == "ros" else "socket"
            yield f"{scheme}://127.0.0.1:{listener.port}", listener


# --- connect() options (issue 14, item 7) ----------------------------------------------


def test_the_cases_cover_every_option_the_driver_takes() -> None:
    assert set(ROBOT_OPTIONS) == set(CONNECT_OPTIONS)
    assert set(LINK_OPTIONS) == set(transports.LINK_OPTIONS)
    assert set(STREAM_OPTIONS) == set(transports.STREAM_OPTIONS)
    assert set(ROS_OPTIONS) == set(ros.ROS_OPTIONS)


@pytest.mark.parametrize(
    ("kind", "name", "value"),
    option_cases("socket", ROBOT_OPTIONS + LINK_OPTIONS + STREAM_OPTIONS)
    + option_cases("serial", ("baudrate", "serial_options", "layout", "stale_timeout"))
    + option_cases("sim", ("layout", "min_command_interval", "map_targets"))
    + option_cases("ros", (*ROS_OPTIONS, "stale_timeout", "first_status_timeout")),
)
async def test_a_bad_option_is_refused_by_connect_itself(kind: str, name: str, value: Any) -> None:
    async with url_of(kind) as (url, listener):
        with pytest.raises(InvalidArgument, match=name) as caught:
            galileo.connect(url, **{name: value})  # raises here: no coroutine ran
        await asyncio.sleep(0)
        assert listener is None or listener.accepted == 0
    assert url in str(caught.value)


async def test_options_are_checked_before_the_link_opens_when_awaited() -> None:
    async with Listener() as listener:
        url = f"socket://127.0.0.1:{listener.port}"
        with pytest.raises(InvalidArgument, match="stale_timeout"):
            await galileo.connect(url, stale_timeout=math.nan)
        with pytest.raises(InvalidArgument, match="min_command_interval"):
            async with galileo.connect(url, min_command_interval=math.nan):
                pass
        assert listener.accepted == 0


@pytest.mark.parametrize(
    ("url", "given", "suggested"),
    [
        ("socket://127.0.0.1:1", "stale_timout", "stale_timeout"),
        ("socket://127.0.0.1:1", "map_target", "map_targets"),
        ("sim://", "min_comand_interval", "min_command_interval"),
        ("/dev/ttyUSB0", "baud_rate", "baudrate"),
        ("ros://127.0.0.1:1", "rpc_timout", "rpc_timeout"),
        ("ros://127.0.0.1:1", "first_status_timeot", "first_status_timeout"),
    ],
)
def test_an_unknown_option_gets_a_near_miss(url: str, given: str, suggested: str) -> None:
    with pytest.raises(InvalidArgument, match=f"did you mean '{suggested}'") as caught:
        galileo.connect(url, **{given: 1})
    assert repr(given) in str(caught.value)
    assert url in str(caught.value)


def test_an_unknown_option_without_a_near_miss_lists_the_known_ones() -> None:
    with pytest.raises(InvalidArgument, match=r"'frobnicate'.*known: .*stale_timeout"):
        galileo.connect("sim://", frobnicate=1)


@pytest.mark.parametrize("url", ["socket://127.0.0.1:1", "sim://", "/dev/ttyUSB0"])
def test_a_ros_option_on_another_link_says_where_it_applies(url: str) -> None:
    with pytest.raises(InvalidArgument, match="rpc_timeout applies to ros:// links only"):
        galileo.connect(url, rpc_timeout=1.0)


@pytest.mark.parametrize("url", ["socket://127.0.0.1:1", "sim://", "/dev/ttyUSB0", "ros://h"])
def test_portable_options_are_taken_by_every_link(url: str) -> None:
    # One set of options serves a fleet of mixed URLs; a link ignores what does not apply.
    galileo.connect(url, baudrate=57600, serial_options={}, connect_timeout=2.0)


def test_reconnect_initial_above_reconnect_max_is_refused() -> None:
    with pytest.raises(InvalidArgument, match=r"reconnect_initial.*reconnect_max"):
        galileo.connect("sim://", reconnect_initial=3.0, reconnect_max=1.0)


def test_the_layout_of_a_ros_link_is_its_own() -> None:
    galileo.connect("ros://h", layout="ros")
    with pytest.raises(InvalidArgument, match="layout"):
        galileo.connect("socket://127.0.0.1:1", layout="ros")
    with pytest.raises(InvalidArgument, match="layout"):
        galileo.connect("ros://h", layout="v2")


@pytest.mark.parametrize(
    "query", ["connect_timeout=nan", "connect_timeout=inf", "connect_timeout=-1"]
)
def test_ros_url_options_are_checked_too(query: str) -> None:
    with pytest.raises(InvalidArgument, match=query.partition("=")[0]):
        galileo.connect(f"ros://127.0.0.1:1?{query}")


@pytest.mark.parametrize(
    "query", ["arrival_distance=nan", "power=inf", "start_pose=nan,0,0", "speed=-1", "drop=nan"]
)
async def test_sim_url_options_are_checked_before_the_simulator_is_built(query: str) -> None:
    url = f"sim://?{query}"
    with anyio.fail_after(5), pytest.raises(InvalidArgument, match=query.partition("=")[0]):
        await galileo.connect(url)


# --- numeric arguments of every Robot method (item 8) ------------------------------------

Call = Callable[[galileo.Robot, Any], Awaitable[object]]


LOST = galileo.LinkState.LOST


def _always_true(status: object) -> bool:
    return True


#: (argument, call with the value in that argument, the values it takes among BAD_VALUES).
ARGUMENTS: dict[str, tuple[str, Call, tuple[Any, ...]]] = {
    "wait_until-timeout": ("timeout", lambda r, v: r.wait_until(_always_true, timeout=v), ()),
    "wait_link-timeout": ("timeout", lambda r, v: r.wait_link(LOST, timeout=v), ()),
    "send-timeout": ("timeout", lambda r, v: r.send(Stop(), timeout=v), ()),
    "start_navigation-timeout": ("timeout", lambda r, v: r.start_navigation(timeout=v), ()),
    "stop_navigation-timeout": ("timeout", lambda r, v: r.stop_navigation(timeout=v), ()),
    "goto-target_id": ("target_id", lambda r, v: r.goto(v), (0,)),
    "goto-timeout": ("timeout", lambda r, v: r.goto(3, timeout=v), ()),
    "goto-accept_timeout": ("accept_timeout", lambda r, v: r.goto(3, accept_timeout=v), ()),
    "goto-progress_timeout": (
        "progress_timeout",
        lambda r, v: r.goto(3, progress_timeout=v),
        (),
    ),
    "goto-cancel_on_exit": ("cancel_on_exit", lambda r, v: r.goto(3, cancel_on_exit=v), (True,)),
    "goto_point-x": ("x", lambda r, v: r.goto_point(v, 1.0), (-1, 0)),
    "goto_point-y": ("y", lambda r, v: r.goto_point(1.0, v), (-1, 0)),
    "goto_point-timeout": ("timeout", lambda r, v: r.goto_point(1.0, 1.0, timeout=v), ()),
    "goto_point-progress_timeout": (
        "progress_timeout",
        lambda r, v: r.goto_point(1.0, 1.0, progress_timeout=v),
        (),
    ),
    "goto_point-cancel_on_exit": (
        "cancel_on_exit",
        lambda r, v: r.goto_point(1.0, 1.0, cancel_on_exit=v),
        (True,),
    ),
    "add_target-x": ("x", lambda r, v: r.add_target(v, 1.0), (-1, 0)),
    "add_target-y": ("y", lambda r, v: r.add_target(1.0, v), (-1, 0)),
    "add_target-timeout": ("timeout", lambda r, v: r.add_target(1.0, 1.0, timeout=v), ()),
    "reset_targets-timeout": ("timeout", lambda r, v: r.reset_targets(timeout=v), ()),
    "pause-timeout": ("timeout", lambda r, v: r.pause(timeout=v), ()),
    "resume-timeout": ("timeout", lambda r, v: r.resume(timeout=v), ()),
    "cancel-timeout": ("timeout", lambda r, v: r.cancel(timeout=v), ()),
    "rotate_to-degrees": ("degrees", lambda r, v: r.rotate_to(v), (-1, 0)),
    "rotate_to-timeout": ("timeout", lambda r, v: r.rotate_to(90, timeout=v), ()),
    "forward-percent": ("percent", lambda r, v: r.forward(v), (0,)),
    "forward-timeout": ("timeout", lambda r, v: r.forward(10, timeout=v), ()),
    "backward-percent": ("percent", lambda r, v: r.backward(v), (0,)),
    "backward-timeout": ("timeout", lambda r, v: r.backward(10, timeout=v), ()),
    "turn_left-percent": ("percent", lambda r, v: r.turn_left(v), (0,)),
    "turn_left-timeout": ("timeout", lambda r, v: r.turn_left(10, timeout=v), ()),
    "turn_right-percent": ("percent", lambda r, v: r.turn_right(v), (0,)),
    "turn_right-timeout": ("timeout", lambda r, v: r.turn_right(10, timeout=v), ()),
    "stop-brake": ("brake", lambda r, v: r.stop(v), (0,)),
    "stop-timeout": ("timeout", lambda r, v: r.stop(timeout=v), ()),
    "zero_speed-brake": ("brake", lambda r, v: r.zero_speed(v), (0,)),
    "start_patrol-dwell": ("dwell", lambda r, v: r.start_patrol(v), (0,)),
    "start_patrol-timeout": ("timeout", lambda r, v: r.start_patrol(timeout=v), ()),
    "stop_patrol-timeout": ("timeout", lambda r, v: r.stop_patrol(timeout=v), ()),
    "set_patrol_dwell-seconds": ("seconds", lambda r, v: r.set_patrol_dwell(v), (0,)),
    "set_patrol_dwell-timeout": ("timeout", lambda r, v: r.set_patrol_dwell(5, timeout=v), ()),
    "start_mapping-timeout": ("timeout", lambda r, v: r.start_mapping(timeout=v), ()),
    "stop_mapping-timeout": ("timeout", lambda r, v: r.stop_mapping(timeout=v), ()),
    "save_map-timeout": ("timeout", lambda r, v: r.save_map(timeout=v), ()),
    "update_map-timeout": ("timeout", lambda r, v: r.update_map(timeout=v), ()),
    "start_charging-timeout": ("timeout", lambda r, v: r.start_charging(timeout=v), ()),
    "stop_charging-timeout": ("timeout", lambda r, v: r.stop_charging(timeout=v), ()),
    "save_dock-timeout": ("timeout", lambda r, v: r.save_dock(timeout=v), ()),
    "shutdown_host-confirm": ("confirm", lambda r, v: r.shutdown_host(confirm=v), (True,)),
}


def test_every_robot_coroutine_has_its_arguments_here() -> None:
    covered = {case.partition("-")[0] for case in ARGUMENTS}
    # Methods without arguments a caller could get wrong.
    covered |= {"close"}
    from tests.packaging.test_public_api import ROBOT_COROUTINES

    assert covered >= ROBOT_COROUTINES


@pytest.mark.parametrize("case", list(ARGUMENTS))
async def test_a_bad_argument_is_refused_and_nothing_is_sent(case: str) -> None:
    argument, call, accepted = ARGUMENTS[case]
    refused = [v for v in BAD_VALUES if not any(v is a or v == a for a in accepted)]
    async with connected(map_targets=5) as (robot, fake):
        for value in refused:
            with anyio.fail_after(5), pytest.raises(InvalidArgument, match=argument) as caught:
                await call(robot, value)
            assert "Overflow" not in repr(caught.value.__cause__), value
        await nothing_was_sent_before_marker(robot, fake)


# --- connect errors name the URL and what was waited for (item 9) --------------------------


async def test_the_connect_timeout_says_what_it_waited_for_and_names_the_url() -> None:
    # A listener that never accepts, its backlog full: the next connect gets no answer.
    with socket.socket() as listener:
        listener.bind(("127.0.0.1", 0))
        listener.listen(0)
        port = listener.getsockname()[1]
        fillers = []
        try:
            for _ in range(4):
                filler = socket.socket()
                fillers.append(filler)
                filler.setblocking(False)
                with contextlib.suppress(BlockingIOError):
                    filler.connect(("127.0.0.1", port))
            url = f"socket://127.0.0.1:{port}"
            with anyio.fail_after(5), pytest.raises(GalileoConnectionError) as caught:
                await galileo.connect(url, connect_timeout=0.2, reconnect=False)
        finally:
            for filler in fillers:
                filler.close()
    message = str(caught.value)
    assert url in message
    assert "no TCP connection within 0.2 s (connect_timeout)" in message


async def test_a_refused_connection_names_the_url() -> None:
    with refused_port() as port:
        url = f"socket://127.0.0.1:{port}"
        with anyio.fail_after(5), pytest.raises(GalileoConnectionError, match=url):
            await galileo.connect(url, reconnect=False)


async def test_a_missing_serial_port_names_the_url() -> None:
    url = "/dev/galileo-validation-test-absent"
    with anyio.fail_after(5), pytest.raises(GalileoConnectionError, match=url):
        await galileo.connect(url, reconnect=False)


async def test_a_silent_serial_port_names_the_url_and_the_wait() -> None:
    with pty_path() as url, anyio.fail_after(5), pytest.raises(GalileoConnectionError) as caught:
        await galileo.connect(url, reconnect=False, first_status_timeout=0.2)
    assert url in str(caught.value)
    assert "no valid status frame arrived within 0.2 s" in str(caught.value)


async def test_an_unreachable_ros_master_names_the_url() -> None:
    with refused_port() as port:
        url = f"ros://127.0.0.1:{port}"
        with anyio.fail_after(10), pytest.raises(GalileoConnectionError, match=url):
            await galileo.connect(url, reconnect=False, connect_timeout=1.0, rpc_timeout=1.0)


async def test_a_silent_ros_master_names_the_url_and_the_wait() -> None:
    held: list[asyncio.StreamWriter] = []

    async def hold(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        held.append(writer)  # read nothing, answer nothing

    server = await asyncio.start_server(hold, "127.0.0.1", 0)
    url = f"ros://127.0.0.1:{server.sockets[0].getsockname()[1]}"
    try:
        with anyio.fail_after(10), pytest.raises(GalileoConnectionError) as caught:
            await galileo.connect(url, reconnect=False, rpc_timeout=0.2)
    finally:
        for writer in held:
            writer.close()
        server.close()
        await server.wait_closed()
    assert url in str(caught.value)
    assert "no reply within 0.2 s (rpc_timeout)" in str(caught.value)


# --- asyncio only (item 10) -----------------------------------------------------------------


@pytest.mark.parametrize("how", ["async with", "await"])
def test_connect_under_trio_says_the_driver_runs_on_asyncio(how: str) -> None:
    pytest.importorskip("trio")
    with socket.socket() as listener:
        listener.bind(("127.0.0.1", 0))
        listener.listen(1)
        listener.setblocking(False)
        url = f"socket://127.0.0.1:{listener.getsockname()[1]}"

        async def main() -> None:
            if how == "await":
                await galileo.connect(url)
            else:
                async with galileo.connect(url):
                    pass

        with pytest.raises(AsyncioRequired, match="the driver runs on asyncio") as caught:
            anyio.run(main, backend="trio")
        assert "trio" in str(caught.value)
        assert url in str(caught.value)
        with pytest.raises(BlockingIOError):
            listener.accept()  # nobody connected


def test_asyncio_required_is_a_galileo_error_and_a_runtime_error() -> None:
    assert issubclass(AsyncioRequired, galileo.GalileoError)
    assert issubclass(AsyncioRequired, RuntimeError)


def test_running_loop_outside_any_loop_says_so() -> None:
    with pytest.raises(AsyncioRequired, match="probe: the driver runs on asyncio, but no asyncio"):
        running_loop("probe")


async def test_running_loop_gives_the_running_loop() -> None:
    assert running_loop("probe") is asyncio.get_running_loop()
