"""ROS 1 link: the master/slave XML-RPC APIs and TCPROS from asyncio, no ROS install needed."""

from __future__ import annotations

from .channel import (
    DEFAULT_MASTER_PORT,
    GOAL_NUM_PARAM,
    ROS_OPTIONS,
    RosChannel,
    check_ros_options,
    parse_ros_url,
    ros_channel,
)
from .messages import (
    CMDS_MD5,
    CMDS_TOPIC,
    CMDS_TYPE,
    STATUS_MD5,
    STATUS_TOPIC,
    STATUS_TYPE,
    StatusMessageDecoder,
    encode_cmds,
)
from .node import NodeStats, RosNode

__all__ = [
    "CMDS_MD5",
    "CMDS_TOPIC",
    "CMDS_TYPE",
    "DEFAULT_MASTER_PORT",
    "GOAL_NUM_PARAM",
    "ROS_OPTIONS",
    "STATUS_MD5",
    "STATUS_TOPIC",
    "STATUS_TYPE",
    "NodeStats",
    "RosChannel",
    "RosNode",
    "StatusMessageDecoder",
    "check_ros_options",
    "encode_cmds",
    "parse_ros_url",
    "ros_channel",
]
