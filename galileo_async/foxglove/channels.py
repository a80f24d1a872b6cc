"""One robot's channels on the Foxglove server, fed from its status and event listeners.

Nothing is encoded for a channel nobody subscribed to; the per-status channels (pose,
transform, status) are published at most ``rate`` times a second, the link and the scene
once a second and when the goal changes; the map (map.py) when a viewer subscribes to it.
"""

from __future__ import annotations

import asyncio
import json
import time
from collections.abc import Sequence
from typing import TYPE_CHECKING

import foxglove
from foxglove.channels import (
    FrameTransformChannel,
    LogChannel,
    PoseInFrameChannel,
    SceneUpdateChannel,
)
from foxglove.messages import (
    Color,
    FrameTransform,
    Log,
    LogLevel,
    Pose,
    PoseInFrame,
    Quaternion,
    SceneEntity,
    SceneEntityDeletion,
    SceneEntityDeletionType,
    SceneUpdate,
    SpherePrimitive,
    TextPrimitive,
    Timestamp,
    Vector3,
)

from ..schemas import LOG_LEVELS, STATUS_SCHEMA_NAME, event_message, log_level, status_json
from .map import MapChannels
from .schemas import LINK_SCHEMA_NAME, link_json, link_schema, status_schema_bytes, yaw_quaternion

if TYPE_CHECKING:
    from ..events import Event
    from ..models import GalileoStatus
    from ..robot import Robot

__all__ = ["MAP_FRAME", "TOPICS", "RobotChannels", "robot_frame"]

#: The fixed frame every pose and scene entity is in.
MAP_FRAME = "map"
#: Each robot's topics, after its ``/name`` prefix.
TOPICS = ("pose", "tf", "status", "link", "scene", "events")

_TARGET_COLOUR = Color(r=0.6, g=0.6, b=0.6, a=0.8)
_GOAL_COLOUR = Color(r=0.1, g=0.8, b=0.2, a=1.0)
_WHITE = Color(r=1.0, g=1.0, b=1.0, a=1.0)
_LEVELS = {
    LOG_LEVELS["INFO"]: LogLevel.Info,
    LOG_LEVELS["WARNING"]: LogLevel.Warning,
    LOG_LEVELS["ERROR"]: LogLevel.Error,
}
_TARGET_SIZE = 0.2
_GOAL_SIZE = 0.35


def robot_frame(name: str) -> str:
    """The frame of robot ``name`` (the child of ``map`` in its transform)."""
    return f"{name}/base_link"


def _json_channel(
    topic: str, name: str, schema: bytes, context: foxglove.Context
) -> foxglove.Channel:
    described = foxglove.Schema(name=name, encoding="jsonschema", data=schema)
    return foxglove.Channel(topic, schema=described, message_encoding="json", context=context)


def _now() -> Timestamp:
    return Timestamp.from_epoch_secs(time.time())


class RobotChannels:
    """The channels ``/name/...`` of one robot, publishing while the listeners are on."""

    def __init__(
        self,
        name: str,
        robot: Robot,
        context: foxglove.Context,
        *,
        rate: float,
        targets: Sequence[tuple[int, float, float]] = (),
    ) -> None:
        self.name, self.robot = name, robot
        self.targets = {target_id: (x, y) for target_id, x, y in targets}
        prefix = f"/{name}"
        self.pose = PoseInFrameChannel(f"{prefix}/pose", context=context)
        self.tf = FrameTransformChannel(f"{prefix}/tf", context=context)
        self.status = _json_channel(
            f"{prefix}/status", STATUS_SCHEMA_NAME, status_schema_bytes(), context
        )
        self.link = _json_channel(f"{prefix}/link", LINK_SCHEMA_NAME, link_schema(), context)
        self.scene = SceneUpdateChannel(f"{prefix}/scene", context=context)
        self.events = LogChannel(f"{prefix}/events", context=context)
        self._period = 1.0 / rate
        self._next = 0.0
        self._goal: int | None = None
        self._frame = robot_frame(name)
        #: The map's channels: only on a link with the HTTP API.
        self.map = (
            None
            if robot.http is None
            else MapChannels(name, robot.http, context, frame_id=MAP_FRAME)
        )
        robot.add_update_listener(self.on_status)
        robot.add_event_listener(self.on_event)

    def close(self) -> asyncio.Task[None] | None:
        """Stop listening and take the channels off the server; a map read cancelled (await it)."""
        self.robot.remove_update_listener(self.on_status)
        self.robot.remove_event_listener(self.on_event)
        for channel in (self.pose, self.tf, self.status, self.link, self.scene, self.events):
            channel.close()
        return None if self.map is None else self.map.close()

    # --- the robot's listeners (on the loop, per status: keep them cheap) ---------------

    def on_status(self, status: GalileoStatus) -> None:
        """Publish the pose, transform and status, at most ``rate`` times a second."""
        now = time.monotonic()
        if now < self._next:
            return
        # From the last slot, not from now: frames come every 33 ms, and now + period would
        # skip to the frame after the slot (7.5 a second for 10).
        self._next = max(self._next + self._period, now)
        goal = _goal_of(status)
        if goal != self._goal:
            self._goal = goal
            self.publish_scene()
        if self.status.has_sinks():
            self.status.log(json.dumps(status_json(status), separators=(",", ":")).encode())
        pose_subscribed, tf_subscribed = self.pose.has_sinks(), self.tf.has_sinks()
        if not (pose_subscribed or tf_subscribed):
            return
        x, y, theta = status.current_pose_x, status.current_pose_y, status.current_angle
        if x is None or y is None or theta is None or (x == y == theta == -1.0):
            return  # no pose in this layout, or the robot does not know where it is
        stamp = _now()
        qx, qy, qz, qw = yaw_quaternion(theta)
        rotation = Quaternion(x=qx, y=qy, z=qz, w=qw)
        if tf_subscribed:
            self.tf.log(FrameTransform(
                timestamp=stamp, parent_frame_id=MAP_FRAME, child_frame_id=self._frame,
                translation=Vector3(x=x, y=y, z=0.0), rotation=rotation,
            ))  # fmt: skip
        if pose_subscribed:
            pose = Pose(position=Vector3(x=x, y=y, z=0.0), orientation=rotation)
            self.pose.log(PoseInFrame(timestamp=stamp, frame_id=MAP_FRAME, pose=pose))

    def on_event(self, event: Event) -> None:
        """Publish ``event`` as a log line; a goal event redraws the scene."""
        if self.events.has_sinks():
            level = _LEVELS.get(log_level(event), LogLevel.Info)
            self.events.log(Log(
                timestamp=_now(), level=level, message=event_message(event), name=self.name,
            ))  # fmt: skip

    # --- once a second, from the server's task ------------------------------------------

    def tick(self) -> None:
        """Publish the link and the scene (a viewer that subscribed since gets them too)."""
        if self.link.has_sinks():
            self.link.log(link_json(self.robot))
        self.publish_scene()
        if self.map is not None:
            self.map.tick()

    def publish_scene(self) -> None:
        """The known targets (grey spheres, labelled) and the current goal (green)."""
        if not self.scene.has_sinks():
            return
        stamp = _now()
        entities = [
            self._marker(stamp, f"target/{target_id}", x, y, str(target_id), goal=False)
            for target_id, (x, y) in self.targets.items()
        ]
        deletions = []
        goal = self._goal
        if goal is not None and goal in self.targets:
            x, y = self.targets[goal]
            entities.append(self._marker(stamp, "goal", x, y, f"{self.name} → {goal}", goal=True))
        else:  # entities stay until deleted: the goal that ended goes
            deletions.append(SceneEntityDeletion(
                timestamp=stamp, type=SceneEntityDeletionType.MatchingId, id=f"{self.name}/goal",
            ))  # fmt: skip
        self.scene.log(SceneUpdate(deletions=deletions, entities=entities))

    def _marker(
        self, stamp: Timestamp, key: str, x: float, y: float, label: str, *, goal: bool
    ) -> SceneEntity:
        size = _GOAL_SIZE if goal else _TARGET_SIZE
        at = Pose(position=Vector3(x=x, y=y, z=0.0), orientation=Quaternion(w=1.0))
        above = Pose(position=Vector3(x=x, y=y, z=size), orientation=Quaternion(w=1.0))
        sphere = SpherePrimitive(
            pose=at, size=Vector3(x=size, y=size, z=size),
            color=_GOAL_COLOUR if goal else _TARGET_COLOUR,
        )  # fmt: skip
        text = TextPrimitive(
            pose=above, billboard=True, font_size=14.0, scale_invariant=True, color=_WHITE,
            text=label,
        )  # fmt: skip
        return SceneEntity(
            timestamp=stamp, frame_id=MAP_FRAME, id=f"{self.name}/{key}",
            spheres=[sphere], texts=[text],
        )  # fmt: skip


def _goal_of(status: GalileoStatus) -> int | None:
    """The goal the status shows working or paused, else None."""
    return status.target_num_id if status.goal_active else None
