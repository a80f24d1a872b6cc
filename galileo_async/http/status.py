"""The WebSocket's /galileo/status JSON (the ROS message's camelCase fields) → GalileoStatus."""

from __future__ import annotations

from typing import Any

from ..errors import InvalidArgument
from ..models import STATUS_FIELDS, GalileoStatus, StatusLayout
from ..protocol._build import trusted_status
from ..protocol.layouts import ENUM_FIELDS
from ..protocol.names import ROS_FIELD_NAMES

__all__ = ["status_from_json"]

_TEMPLATE: dict[str, Any] = {**dict.fromkeys(STATUS_FIELDS), "layout": StatusLayout.ROS}


def status_from_json(message: Any) -> GalileoStatus:
    """One decoded JSON message as a status; InvalidArgument when it is not one."""
    if not isinstance(message, dict) or "navStatus" not in message:
        raise InvalidArgument("not a GalileoStatus message")
    values = _TEMPLATE.copy()
    for ros, ours in ROS_FIELD_NAMES.items():
        value = message.get(ros)
        if value is None:
            continue
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise InvalidArgument(f"{ros} is not a number: {value!r}")
        enum_type = ENUM_FIELDS.get(ours)
        if enum_type is not None:
            try:
                value = enum_type(int(value))
            except ValueError:
                raise InvalidArgument(f"{ros}: unknown value {value!r}") from None
        values[ours] = value
    header = message.get("header")
    if isinstance(header, dict) and isinstance(header.get("seq"), int):
        values["time_stamp"] = header["seq"]
    return trusted_status(values)
