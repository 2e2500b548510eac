"""Temperature dependence shared by the pixel's leakage mechanisms (dark current, leak)."""

from __future__ import annotations

import math

#: Temperature (K) at which presets state dark current and leak rates (27 degC).
REFERENCE_TEMPERATURE_K = 300.0
#: The hottest sensor: 500 K, above any silicon chip's rating (~400 K); 1e300 K overflowed the leakage to NaN.
MAX_TEMPERATURE_K = 500.0


def thermal_factor(temperature_k: float, doubling_k: float) -> float:
    """2 ** ((T - T_ref) / doubling_k): how much a leakage current grows from
    :data:`REFERENCE_TEMPERATURE_K` to ``temperature_k`` (1 for an infinite doubling interval)."""
    if math.isinf(doubling_k):
        return 1.0
    from gevsim._portable import exp_scalar

    return float(exp_scalar((temperature_k - REFERENCE_TEMPERATURE_K) / doubling_k * 0.6931471805599453))  # ln 2
