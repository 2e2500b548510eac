"""Event data types (DESIGN.md, Data contracts).

Brightness events use tonic's fields so tonic transforms work on them:
``x`` int16, ``y`` int16, ``t`` int64 microseconds, ``p`` bool (True = ON).
Gradient events add ``axis`` (uint8: 0 = X, 1 = Y) and carry ``p`` as int8 (+1/-1).
"""

from __future__ import annotations

import numpy as np

BRIGHTNESS_DTYPE = np.dtype([("x", "<i2"), ("y", "<i2"), ("t", "<i8"), ("p", "?")])
GRADIENT_DTYPE = np.dtype([("x", "<i2"), ("y", "<i2"), ("t", "<i8"), ("p", "i1"), ("axis", "u1")])
AXIS_X, AXIS_Y = 0, 1


def empty(dtype: np.dtype) -> np.ndarray:
    """A zero-length event array of ``dtype``."""
    return np.zeros(0, dtype=dtype)


def is_gradient(events: np.ndarray) -> bool:
    """True for gradient events (they have an ``axis`` field)."""
    return events.dtype.names is not None and "axis" in events.dtype.names


def check_events(events: np.ndarray, *, name: str = "events") -> np.ndarray:
    """Validate an event array: one of the two dtypes, timestamps non-decreasing."""
    if not isinstance(events, np.ndarray) or events.dtype not in (BRIGHTNESS_DTYPE, GRADIENT_DTYPE):
        got = getattr(events, "dtype", type(events).__name__)
        raise TypeError(f"{name} must be a structured array of BRIGHTNESS_DTYPE or GRADIENT_DTYPE, got {got}")
    if len(events) > 1 and np.any(np.diff(events["t"]) < 0):
        raise ValueError(f"{name} timestamps must be non-decreasing")
    return events
