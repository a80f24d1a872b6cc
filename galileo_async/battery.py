"""The battery's charge in percent, estimated from its voltage (the robot reports volts only)."""

from __future__ import annotations

import math

__all__ = ["BATTERY_CURVE", "battery_charge"]

#: Volts → percent of a 24 V pack at rest, linear between the points. The robot reports
#: voltage only (docs/protocol.md §1 ``power``), so every percentage is an estimate.
BATTERY_CURVE: tuple[tuple[float, float], ...] = (
    (22.0, 0.0),
    (23.5, 10.0),
    (24.5, 30.0),
    (25.5, 60.0),
    (26.5, 85.0),
    (28.0, 100.0),
)


def battery_charge(volts: float) -> float:
    """Estimated charge in percent (0..100, one decimal) for ``volts`` on BATTERY_CURVE."""
    if not math.isfinite(volts):
        return 0.0
    (low_v, low_p), *rest = BATTERY_CURVE
    if volts <= low_v:
        return low_p
    for high_v, high_p in rest:
        if volts <= high_v:
            return round(low_p + (high_p - low_p) * (volts - low_v) / (high_v - low_v), 1)
        low_v, low_p = high_v, high_p
    return 100.0
