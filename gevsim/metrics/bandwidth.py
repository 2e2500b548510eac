"""Event-stream bandwidth: event rates and the bit rates they need."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from gevsim._validate import integer, real, real_array


def bits_per_second(events_per_second: ArrayLike, *, bits_per_event: float) -> float | np.ndarray:
    """Bit rate (bit/s) of a stream of ``events_per_second`` events coded with ``bits_per_event`` bits each.

    Works elementwise on arrays; both arguments must be finite and >= 0.
    """
    rate = real_array(events_per_second, "events_per_second", nonnegative=True, dtype=np.float64)
    out = rate * real(bits_per_event, "bits_per_event", low=0.0)
    return float(out) if out.ndim == 0 else out


def events_per_second(n_events: int, *, duration_s: float) -> float:
    """Mean event rate (events/s) of ``n_events`` events over ``duration_s`` seconds."""
    return integer(n_events, "n_events", low=0) / real(duration_s, "duration_s", low=0.0, low_open=True)
