"""VDA 5050 2.0 vehicle adapter: a Galileo robot as a vehicle of any VDA 5050 master control.

Needs the ``vda5050`` extra (aiomqtt). See docs/vda5050.md.
"""

from __future__ import annotations

from .config import (
    MAX_VISUALIZATION_RATE,
    BrokerAddress,
    VehicleConfig,
    parse_broker_url,
    redact_url,
)
from .fleet import FleetVehicle, VehicleFleet
from .order import OrderProgress, Rejection, check_order
from .shutdown import ShutdownReport
from .vehicle import Vehicle, run_vehicles

__all__ = [
    "MAX_VISUALIZATION_RATE",
    "BrokerAddress",
    "FleetVehicle",
    "OrderProgress",
    "Rejection",
    "ShutdownReport",
    "Vehicle",
    "VehicleConfig",
    "VehicleFleet",
    "check_order",
    "parse_broker_url",
    "redact_url",
    "run_vehicles",
]
