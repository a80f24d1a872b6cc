"""Unicycle kinematics and a simple go-to-point controller (pure functions)."""

from __future__ import annotations

import math

from .config import SimConfig

__all__ = ["HEADING_TOLERANCE", "Body", "ramp", "steer", "turn_toward", "wrap_angle"]

#: Above this heading error the controller turns in place before driving, radians.
HEADING_TOLERANCE = 0.3
_TURN_GAIN = 3.0


def wrap_angle(angle: float) -> float:
    """Map an angle to (-pi, pi]."""
    wrapped = math.remainder(angle, math.tau)
    return math.pi if wrapped == -math.pi else wrapped


def turn_toward(theta: float, goal: float, max_turn_rate: float, dt: float) -> tuple[float, bool]:
    """Angular speed that turns to heading ``goal`` this step, and whether it gets there."""
    error = wrap_angle(goal - theta)
    if abs(error) <= max_turn_rate * dt:
        return error / dt if dt > 0 else 0.0, True
    return math.copysign(max_turn_rate, error), False


def steer(
    pose: tuple[float, float, float],
    target: tuple[float, float],
    max_speed: float,
    max_turn_rate: float,
    dt: float,
) -> tuple[float, float, bool]:
    """(v, w, reaches): speeds toward ``target``; reaches when this step can land on it."""
    x, y, theta = pose
    dx, dy = target[0] - x, target[1] - y
    distance = math.hypot(dx, dy)
    if distance == 0.0:
        return 0.0, 0.0, True
    error = wrap_angle(math.atan2(dy, dx) - theta)
    turn = max(-max_turn_rate, min(max_turn_rate, _TURN_GAIN * error))
    if abs(error) > HEADING_TOLERANCE:
        return 0.0, turn, False
    speed = min(max_speed * math.cos(error), distance / dt if dt > 0 else max_speed)
    return speed, turn, speed * dt >= distance - 1e-9


def ramp(current: float, command: float, limit: float) -> float:
    """Move ``current`` toward ``command``: speeding up by at most ``limit``, braking at once."""
    if command * current < 0.0:  # reversing: brake to zero, then accelerate
        current = 0.0
    if abs(command) <= abs(current):
        return command
    return current + max(-limit, min(limit, command - current))


class Body:
    """A unicycle: pose, commanded (control) and measured (current) speeds, limits."""

    def __init__(self, config: SimConfig) -> None:
        self.config = config
        self.x, self.y, self.theta = config.start_pose
        self.control_v = self.control_w = 0.0
        self.current_v = self.current_w = 0.0
        #: The fastest a goal is driven, m/s (the HTTP config's navigation_speed).
        self.navigation_speed = config.max_speed

    def distance_to(self, point: tuple[float, float]) -> float:
        """Metres from the robot to ``point``."""
        return math.hypot(point[0] - self.x, point[1] - self.y)

    def halt(self) -> None:
        """Zero commanded and measured speeds at once."""
        self.control_v = self.control_w = self.current_v = self.current_w = 0.0

    def drive_to(self, point: tuple[float, float], dt: float, *, land: bool = True) -> bool:
        """Command speeds toward ``point``; True (and placed on it, halted) on arrival."""
        config = self.config
        pose = (self.x, self.y, self.theta)
        v, w, reaches = steer(pose, point, self.navigation_speed, config.max_turn_rate, dt)
        self.control_v, self.control_w = v, w
        reaches = reaches or self.distance_to(point) <= config.arrival_distance
        if reaches and land:
            self.x, self.y = point
            self.halt()
        return reaches and land

    def integrate(self, dt: float) -> None:
        """Bring measured speeds toward the command (acceleration-limited) and move."""
        if not (self.control_v or self.control_w or self.current_v or self.current_w):
            return  # standing still: nothing to do (most robots, most of the time)
        config = self.config
        self.current_v = ramp(self.current_v, self.control_v, config.acceleration * dt)
        self.current_w = ramp(self.current_w, self.control_w, config.angular_acceleration * dt)
        if self.current_v or self.current_w:
            heading = self.theta + self.current_w * dt / 2
            self.x += self.current_v * dt * math.cos(heading)
            self.y += self.current_v * dt * math.sin(heading)
            self.theta = wrap_angle(self.theta + self.current_w * dt)
