"""Velocities: the serial f/b and c/d percentages for one, and the Twist command of ros://."""

from __future__ import annotations

from dataclasses import dataclass

from .._checks import check_number
from ..errors import InvalidArgument
from .commands import Backward, Command, Forward, Goto, TurnLeft, TurnRight

__all__ = ["PoseGoal", "Velocity", "speed_commands"]


@dataclass(frozen=True, slots=True)
class Velocity(Command):
    """``linear`` m/s and ``angular`` rad/s as one geometry_msgs/Twist; ros:// links only.

    The serial protocol has no such command: serial links write speed_commands() instead.
    """

    linear: float
    angular: float

    def __post_init__(self) -> None:
        check_number("linear", self.linear)
        check_number("angular", self.angular)

    def payload(self) -> bytes:
        raise InvalidArgument("a Velocity has no serial encoding (use forward/turn_left …)")


@dataclass(frozen=True, slots=True)
class PoseGoal(Goto):
    """A goal by pose, ``x``, ``y`` m and ``theta`` rad; http:// links only (a nav task).

    The robot shows such a goal as target -2 (docs/protocol.md §5.4), which is its ``target_id``.
    """

    target_id: int = -2
    x: float = 0.0
    y: float = 0.0
    theta: float = 0.0

    def __post_init__(self) -> None:
        if self.target_id != -2:
            raise InvalidArgument("a PoseGoal is target -2")
        check_number("x", self.x)
        check_number("y", self.y)
        check_number("theta", self.theta)

    def payload(self) -> bytes:
        raise InvalidArgument("a PoseGoal has no serial encoding (use goto_point)")


def speed_commands(
    linear: float, angular: float, *, max_linear: float, max_angular: float
) -> tuple[Command, Command]:
    """The two commands, linear first, that make the vendor's node publish this velocity.

    The vendor keeps linear and angular separately (docs/protocol.md §6.2): ``f``/``b`` set
    linear.x = max_linear·p/100 and leave angular alone; ``c``/``d`` set angular.z =
    max_angular·p/100/s, s = max(1, |linear.x|) read at that moment, and leave linear
    alone. So linear goes first and the angular percentage is multiplied by s; a zero
    component is ``f 0`` / ``c 0`` (``s`` would zero both). InvalidArgument when a
    percentage would exceed 100. Over 1 % the node raises |angular.z| to at least 0.4
    rad/s (0.2 on kinetic builds): smaller turns cannot be sent over serial.
    """
    linear_percent = round(abs(linear) / max_linear * 100)
    sent_linear = max_linear * linear_percent / 100
    scale = max(1.0, sent_linear)
    angular_percent = round(abs(angular) * scale / max_angular * 100)
    if linear_percent > 100 or angular_percent > 100:
        raise InvalidArgument(
            f"linear {linear} m/s, angular {angular} rad/s exceed the robot's limits "
            f"({max_linear} m/s, {max_angular} rad/s at that linear speed)"
        )
    forward: Command = Backward(linear_percent) if linear < 0 else Forward(linear_percent)
    turn: Command = TurnRight(angular_percent) if angular < 0 else TurnLeft(angular_percent)
    return forward, turn
