"""The one description of the options: ConnectOptions, a TypedDict whose fields carry Options."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Annotated, Any, Literal, TypedDict, get_args, get_type_hints

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
    DEFAULT_PROGRESS_TIMEOUT,
    DEFAULT_RECONNECT_INITIAL,
    DEFAULT_RECONNECT_MAX,
    DEFAULT_RPC_TIMEOUT,
    DEFAULT_STALE_RECONNECT,
    DEFAULT_STALE_TIMEOUT,
    DEFAULT_WAIT_TIMEOUT,
    FIRST_STATUS_TIMEOUT,
    Check,
    check_baudrate,
    check_degrees,
    check_hosts,
    check_map_targets,
    check_metres,
    check_name,
    check_queue,
    check_ros_layout,
    check_serial_options,
    check_speed_limit,
    check_stale_reconnect,
    check_stream_layout,
    seconds_or_zero,
    timeout_not_none,
)

__all__ = ["LINK_KINDS", "OPTIONS", "OWNERS", "ConnectOptions", "Option", "Owner"]

#: The link kinds (transports.link_kind): what a URL opens.
LINK_KINDS = ("serial", "socket", "udp", "sim", "ros")
#: Who takes an option: the Robot, connect() itself, or the link.
Owner = Literal["robot", "connect", "link"]
OWNERS: tuple[Owner, ...] = ("robot", "connect", "link")


@dataclasses.dataclass(frozen=True)
class Option:
    """One option: its default, owner, the link kinds that take it (None: all), doc, check.

    ``name`` and ``type`` come from its field of ConnectOptions; ``by_kind``: a check of
    its own on some link kinds.
    """

    default: Any
    doc: str
    check_value: Check
    owner: Owner = "link"
    kinds: frozenset[str] | None = None
    by_kind: Mapping[str, Check] = dataclasses.field(default_factory=dict)
    name: str = ""
    type: Any = None

    def takes(self, kind: str | None) -> bool:
        """True when a link of ``kind`` (None: any) takes this option."""
        return self.kinds is None or kind is None or kind in self.kinds

    def check(self, value: object, kind: str | None = None) -> None:
        """Raise InvalidArgument, naming the option, when a ``kind`` link cannot use ``value``."""
        self.by_kind.get(kind or "", self.check_value)(self.name, value)


_ROS = frozenset({"ros"})
_LAYOUT_KINDS = frozenset({"serial", "socket", "sim", "ros"})


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
    # Every link's (BaseLink's).
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
            "seconds without a valid frame before the link counts as stale and waiting operations fail (None: off)",  # noqa: E501
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
            "seconds a TCP connect (`socket://`) or a ROS connection (`ros://`) may take (ignored elsewhere)",  # noqa: E501
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
            by_kind={"ros": check_ros_layout},
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
            DEFAULT_RPC_TIMEOUT, "bound in seconds on each XML-RPC call", check_seconds, kinds=_ROS
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


def _described() -> dict[str, Option]:
    hints = get_type_hints(ConnectOptions, include_extras=True)
    described = {}
    for name, hint in hints.items():
        base, option = get_args(hint)[:2]
        described[name] = dataclasses.replace(option, name=name, type=base)
    return described


#: Every option of connect(), by name, in the order of ConnectOptions.
OPTIONS: Mapping[str, Option] = _described()
