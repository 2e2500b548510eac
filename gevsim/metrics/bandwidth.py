"""Event-stream bandwidth: event rates and the bit rates they need."""

from __future__ import annotations

import numpy as np


def bits_per_second(events_per_second, *, bits_per_event):
    """Bit rate (bit/s) of a stream of ``events_per_second`` events coded with ``bits_per_event`` bits each.

    Works elementwise on arrays; both arguments must be finite and >= 0.
    """
    rate = np.asarray(events_per_second, dtype=np.float64)
    if not np.all(np.isfinite(rate)) or np.any(rate < 0):
        raise ValueError(f"events_per_second must be finite and >= 0, got {events_per_second!r}")
    if not (np.isfinite(bits_per_event) and bits_per_event >= 0):
        raise ValueError(f"bits_per_event must be finite and >= 0, got {bits_per_event!r}")
    out = rate * float(bits_per_event)
    return float(out) if out.ndim == 0 else out


def events_per_second(n_events, *, duration_s):
    """Mean event rate (events/s) of ``n_events`` events over ``duration_s`` seconds."""
    if not (np.isfinite(duration_s) and duration_s > 0):
        raise ValueError(f"duration_s must be finite and > 0, got {duration_s!r}")
    if not isinstance(n_events, (int, np.integer)) or n_events < 0:
        raise ValueError(f"n_events must be a non-negative integer, got {n_events!r}")
    return int(n_events) / float(duration_s)
