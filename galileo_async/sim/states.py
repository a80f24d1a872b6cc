"""Wire values of the simulated robot's goal and charge states (docs/protocol.md §1)."""

from __future__ import annotations

__all__ = [
    "ACTIVE", "CHARGED", "CHARGE_FREE", "CHARGING", "DOCKING", "EPSILON", "ERROR", "FINDING",
    "FREE", "INVALID", "PAUSED", "WORKING",
]  # fmt: skip

#: target_status values.
FREE, WORKING, PAUSED, ERROR, INVALID = 0, 1, 2, 3, -1
#: A goal in progress (the planner holds it).
ACTIVE = (WORKING, PAUSED)
#: charge_status values.
CHARGE_FREE, CHARGING, CHARGED, FINDING, DOCKING = 0, 1, 2, 3, 4
EPSILON = 1e-9  # simulated time is a sum of 1/30 steps
