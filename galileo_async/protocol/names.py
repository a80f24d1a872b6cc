"""The status fields' names in the ROS message, also the HTTP API's WebSocket JSON keys."""

from __future__ import annotations

__all__ = ["ROS_FIELD_NAMES"]

#: ROS field name → GalileoStatus field, for every field any version of the message has.
ROS_FIELD_NAMES: dict[str, str] = {
    "navStatus": "nav_status",
    "visualStatus": "visual_status",
    "mapStatus": "map_status",
    "gcStatus": "gc_status",
    "gbaStatus": "gba_status",
    "chargeStatus": "charge_status",
    "loopStatus": "loop_status",
    "power": "power",
    "targetNumID": "target_num_id",
    "targetStatus": "target_status",
    "targetDistance": "target_distance",
    "angleGoalStatus": "angle_goal_status",
    "controlSpeedX": "control_speed_x",
    "controlSpeedTheta": "control_speed_theta",
    "currentSpeedX": "current_speed_x",
    "currentSpeedTheta": "current_speed_theta",
    "currentPosX": "current_pose_x",
    "currentPosY": "current_pose_y",
    "currentAngle": "current_angle",
    "busyStatus": "busy_status",
}
