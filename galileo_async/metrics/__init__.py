"""Prometheus metrics of robots and fleets (the extra ``[metrics]``): Metrics, serve_metrics.

docs/observability.md#prometheus-metrics lists the metrics and the odometer's rule.
"""

from __future__ import annotations

from .collector import GOAL_ENDINGS, ODOMETER_JUMP, ODOMETER_STEP, Metrics
from .server import DEFAULT_METRICS_HOST, DEFAULT_METRICS_PORT, MetricsServer, serve_metrics

__all__ = [
    "DEFAULT_METRICS_HOST",
    "DEFAULT_METRICS_PORT",
    "GOAL_ENDINGS",
    "ODOMETER_JUMP",
    "ODOMETER_STEP",
    "Metrics",
    "MetricsServer",
    "serve_metrics",
]
