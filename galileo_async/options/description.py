"""The one description of the options: ConnectOptions, a TypedDict whose fields carry Options."""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Mapping
from typing import Annotated, Any, TypedDict, get_args, get_type_hints

from pydantic import SecretStr

from .._checks import check_bool, check_seconds, check_timeout
from ..transitions import DEFAULT_ARRIVE_TOLERANCE
from .checks import (
    DEFAULT_ACCEPT_TIMEOUT,
    DEFAULT_ANGLE_TOLERANCE,
    DEFAULT_BAUDRATE,
    DEFAULT_CONNECT_TIMEOUT,
    DEFAULT_DRAIN_TIMEOUT,
    DEFAULT_GOAL_TIMEOUT,
    DEFAULT_MASTER_CHECK_INTERVAL,
    DEFAULT_MAX_ANGULAR_SPEED,
    DEFAULT_MAX_LINEAR_SPEED,
    DEFAULT_MAX_QUEUED_COMMANDS,
    DEFAULT_MIN_COMMAND_INTERVAL,
    DEFAULT_PING_INTERVAL,
    DEFAULT_PROGRESS_TIMEOUT,
    DEFAULT_RECONNECT_INITIAL,
    DEFAULT_RECONNECT_MAX,
    DEFAULT_REQUEST_TIMEOUT,
    DEFAULT_RPC_TIMEOUT,
    DEFAULT_STALE_RECONNECT,
    DEFAULT_STALE_TIMEOUT,
    DEFAULT_WAIT_TIMEOUT,
    DEFAULT_WS_PORT,
    FIRST_STATUS_TIMEOUT,
    check_baudrate,
    check_ca_file,
    check_degrees,
    check_hosts,
    check_http_layout,
    check_map_targets,
    check_metres,
    check_name,
    check_port,
    check_queue,
    check_ros_layout,
    check_secret,
    check_serial_options,
    check_speed_limit,
    check_stale_reconnect,
    check_stream_layout,
    seconds_or_zero,
    timeout_not_none,
)
from .option import LINK_KINDS, OWNERS, Option, Owner

__all__ = ["LINK_KINDS", "OPTIONS", "OWNERS", "ConnectOptions", "Option", "Owner"]


_ROS = frozenset({"ros"})
_HTTP = frozenset({"http"})
_LAYOUT_KINDS = frozenset({"serial", "socket", "sim", "ros", "http"})


class ConnectOptions(TypedDict, total=False):
    """The keyword options of ``connect(url, **options)``, each described by its Option."""

    # The Robot's (every link kind).
    map_targets: Annotated[
        int | None,
        Option(
            None,
            "number of targets in the robot's map; `goto_point`/`add_target` need it (the serial link cannot read it); on `sim://` taken from the simulator's map, on `ros://` from `/galileo/goal_num`; given where the link can tell, a different value is refused",  # noqa: E501
            check_map_targets,
            "robot",
        ),
    ]
    accept_timeout: Annotated[
        float,
        Option(
            DEFAULT_ACCEPT_TIMEOUT,
            "seconds for a goal to show as working after `g N`",
            timeout_not_none,
            "robot",
        ),
    ]
    arrive_tolerance: Annotated[
        float,
        Option(
            DEFAULT_ARRIVE_TOLERANCE,
            "metres: a goal that ends free this close to its target has arrived",
            check_metres,
            "robot",
        ),
    ]
    goal_timeout: Annotated[
        float | None,
        Option(
            DEFAULT_GOAL_TIMEOUT,
            "seconds a `goto`/`goto_point` called without `timeout` may take (None: no limit)",
            check_timeout,
            "robot",
        ),
    ]
    wait_timeout: Annotated[
        float | None,
        Option(
            DEFAULT_WAIT_TIMEOUT,
            "seconds `wait_until` called without `timeout` waits (None: no limit)",
            check_timeout,
            "robot",
        ),
    ]
    progress_timeout: Annotated[
        float | None,
        Option(
            DEFAULT_PROGRESS_TIMEOUT,
            "seconds of unpaused goal time without progress before a `goto`/`goto_point` called without `progress_timeout` fails with `GoalStalled` (None: never)",  # noqa: E501
            check_timeout,
            "robot",
        ),
    ]
    angle_tolerance: Annotated[
        float,
        Option(
            DEFAULT_ANGLE_TOLERANCE,
            "degrees (0–180): `rotate_to` to a heading the robot already has within this much returns at once and sends nothing",  # noqa: E501
            check_degrees,
            "robot",
        ),
    ]
    max_linear_speed: Annotated[
        float,
        Option(
            DEFAULT_MAX_LINEAR_SPEED,
            "m/s at 100 % of `f`/`b` (the vendor's `max_vel`); `drive()` converts its speeds with it and refuses faster ones; above 0, at most 10",  # noqa: E501
            check_speed_limit,
            "robot",
        ),
    ]
    max_angular_speed: Annotated[
        float,
        Option(
            DEFAULT_MAX_ANGULAR_SPEED,
            "rad/s at 100 % of `c`/`d` (the vendor's `max_theta`: 1.5 on kinetic builds, 1.2 on noetic ones: set 1.2 there); above 0, at most 10",  # noqa: E501
            check_speed_limit,
            "robot",
        ),
    ]
    # connect()'s own.
    first_status_timeout: Annotated[
        float | None,
        Option(
            FIRST_STATUS_TIMEOUT,
            "seconds `connect` waits for the first valid frame, whatever `stale_timeout` is (None: do not wait)",  # noqa: E501
            check_timeout,
            "connect",
        ),
    ]
    control_socket: Annotated[
        bool,
        Option(
            False,
            "serve a control socket while connected, so that other processes of this user (`galileo stop`, `cancel`, `pause`) stop, cancel or pause the robot through this one (serial device paths and `udp://`; taken and ignored elsewhere; [the control socket](#the-control-socket))",  # noqa: E501
            check_bool,
            "connect",
        ),
    ]
    # Every link kind's (the Link's).
    reconnect: Annotated[
        bool,
        Option(
            True,
            "reconnect after a drop, with capped exponential back-off over the whole outage",
            check_bool,
        ),
    ]
    reconnect_initial: Annotated[
        float,
        Option(
            DEFAULT_RECONNECT_INITIAL,
            "seconds before the first retry of an outage; each further one waits twice the last",
            check_seconds,
        ),
    ]
    reconnect_max: Annotated[
        float,
        Option(
            DEFAULT_RECONNECT_MAX,
            "longest wait between two retries (at least `reconnect_initial`)",
            check_seconds,
        ),
    ]
    stale_timeout: Annotated[
        float | None,
        Option(
            DEFAULT_STALE_TIMEOUT,
            "seconds without a valid frame before the link counts as stale and waiting operations fail; a goal being followed goes on until the link is lost (None: off)",  # noqa: E501
            check_timeout,
        ),
    ]
    stale_reconnect: Annotated[
        float | None,
        Option(
            DEFAULT_STALE_RECONNECT,
            "silent for this many `stale_timeout`s, the peer is taken for dead and the link reconnects (None: stay stale; at least 1)",  # noqa: E501
            check_stale_reconnect,
        ),
    ]
    min_command_interval: Annotated[
        float,
        Option(
            DEFAULT_MIN_COMMAND_INTERVAL,
            "least seconds between two command writes (0 allowed)",
            seconds_or_zero,
        ),
    ]
    drain_timeout: Annotated[
        float,
        Option(
            DEFAULT_DRAIN_TIMEOUT,
            "longest the transport may hold unsent bytes before the queued sends fail",
            check_seconds,
        ),
    ]
    max_queued_commands: Annotated[
        int,
        Option(
            DEFAULT_MAX_QUEUED_COMMANDS,
            "commands waiting for the writer; a further `send` waits for a place",
            check_queue,
        ),
    ]
    # Taken by every kind, ignored where they do not apply (one set serves a mixed fleet).
    baudrate: Annotated[
        int,
        Option(
            DEFAULT_BAUDRATE, "serial speed (serial ports only, ignored elsewhere)", check_baudrate
        ),
    ]
    serial_options: Annotated[
        Mapping[str, Any] | None,
        Option(
            None,
            'further pyserial settings (serial ports only, ignored elsewhere); ports are opened exclusively, `{"exclusive": False}` shares one',  # noqa: E501
            check_serial_options,
        ),
    ]
    connect_timeout: Annotated[
        float,
        Option(
            DEFAULT_CONNECT_TIMEOUT,
            "seconds a TCP connect (`socket://`), a ROS connection (`ros://`) or the opening of the status WebSocket (`http://`) may take (ignored elsewhere)",  # noqa: E501
            check_seconds,
        ),
    ]
    # Byte streams and ROS.
    layout: Annotated[
        str | None,
        Option(
            None,
            "pin the status layout (`v2`, `v2_truncated`, `v1`, `v1_charge`; `ros` on `ros://`); None: detect it",  # noqa: E501
            check_stream_layout,
            kinds=_LAYOUT_KINDS,
            by_kind={"ros": check_ros_layout, "http": check_http_layout},
        ),
    ]
    # ros:// links' own (ros.md).
    host: Annotated[
        str | None,
        Option(
            None,
            "the address this process advertises to the robot's master (default: `ROS_IP`, `ROS_HOSTNAME`, else the address that routes to the master)",  # noqa: E501
            check_name,
            kinds=_ROS,
        ),
    ]
    bind: Annotated[
        str | None,
        Option(
            None,
            "where the XML-RPC and TCPROS servers listen (default: `host` when it is an IP, else `0.0.0.0`)",  # noqa: E501
            check_name,
            kinds=_ROS,
        ),
    ]
    node_name: Annotated[
        str | None,
        Option(
            None, "the ROS caller id (default: `/galileo_async_<pid>_<n>`)", check_name, kinds=_ROS
        ),
    ]
    rpc_timeout: Annotated[
        float,
        Option(
            DEFAULT_RPC_TIMEOUT,
            "bound in seconds on each XML-RPC call",
            check_seconds,
            kinds=_ROS,
        ),
    ]
    master_check_interval: Annotated[
        float,
        Option(
            DEFAULT_MASTER_CHECK_INTERVAL,
            "seconds between polls of the master, to notice a restart",
            check_seconds,
            kinds=_ROS,
        ),
    ]
    hosts: Annotated[
        str | Mapping[str, str] | None,
        Option(
            None,
            '`"name=ip,…"` or `{name: ip}`: where to reach the host names the robot\'s nodes advertise',  # noqa: E501
            check_hosts,
            kinds=_ROS,
        ),
    ]

    # http:// and https:// links' own (transports.md).
    username: Annotated[
        str | None,
        Option(
            None,
            "user name for the API's token (token checking is off by default)",
            check_name,
            kinds=_HTTP,
        ),
    ]
    password: Annotated[
        str | SecretStr | None,
        Option(
            None,
            "password for the API's token (a string or pydantic `SecretStr`; never logged or shown)",  # noqa: E501
            check_secret,
            kinds=_HTTP,
        ),
    ]
    token: Annotated[
        str | SecretStr | None,
        Option(
            None, "an API token got elsewhere (never logged or shown)", check_secret, kinds=_HTTP
        ),
    ]
    ws_port: Annotated[
        int,
        Option(
            DEFAULT_WS_PORT,
            "the WebSocket port of the robot's API (status)",
            check_port,
            kinds=_HTTP,
        ),
    ]
    request_timeout: Annotated[
        float,
        Option(
            DEFAULT_REQUEST_TIMEOUT,
            "seconds one REST call may take before it fails with `HttpTimeout` (an `HttpError` and a `TimeoutError`)",  # noqa: E501
            check_seconds,
            kinds=_HTTP,
        ),
    ]
    ping_interval: Annotated[
        float,
        Option(
            DEFAULT_PING_INTERVAL,
            "seconds between the WebSocket pings of the link's own timer",
            check_seconds,
            kinds=_HTTP,
        ),
    ]
    ca_file: Annotated[
        str | os.PathLike[str] | None,
        Option(
            None,
            "https:// and wss:// trust the CAs in this PEM file (None: the system's); "
            "the certificate and host name are always verified",
            check_ca_file,
            kinds=_HTTP,
        ),
    ]


def _described() -> dict[str, Option]:
    hints = get_type_hints(ConnectOptions, include_extras=True)
    described = {}
    for name, hint in hints.items():
        base, option = get_args(hint)[:2]
        described[name] = dataclasses.replace(option, name=name, type=base)
    return described


#: Every option of connect(), by name, in the order of ConnectOptions.
OPTIONS: Mapping[str, Option] = _described()
