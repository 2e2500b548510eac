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


def check_events(events: np.ndarray, *, name: str = "events", shape: tuple[int, int] | None = None) -> np.ndarray:
    """Validate an event array: one of the two dtypes, timestamps non-decreasing; gradient events with
    ``axis`` 0 or 1 and ``p`` +1 or -1; with ``shape`` (H, W), every x in [0, W) and y in [0, H). Values
    from a file are untrusted: compiled kernels index arrays with them and do not check."""
    if not isinstance(events, np.ndarray) or events.dtype not in (BRIGHTNESS_DTYPE, GRADIENT_DTYPE):
        got = getattr(events, "dtype", type(events).__name__)
        raise TypeError(f"{name} must be a structured array of BRIGHTNESS_DTYPE or GRADIENT_DTYPE, got {got}")
    if len(events) > 1 and np.any(np.diff(events["t"]) < 0):
        raise ValueError(f"{name} timestamps must be non-decreasing")
    if len(events) and is_gradient(events):
        bad = np.count_nonzero(events["axis"] > 1)
        if bad:
            raise ValueError(f"{name}: {bad} gradient events have an axis other than 0 or 1 "
                             f"(e.g. {int(events['axis'][events['axis'] > 1][0])})")
        bad = np.count_nonzero((events["p"] != 1) & (events["p"] != -1))
        if bad:
            raise ValueError(f"{name}: {bad} gradient events have p other than +1 or -1")
    if shape is not None and len(events):
        h, w = shape
        outside = (events["x"] < 0) | (events["x"] >= w) | (events["y"] < 0) | (events["y"] >= h)
        if np.any(outside):
            i = int(np.flatnonzero(outside)[0])
            raise ValueError(f"{name}: {int(np.count_nonzero(outside))} events lie outside the {w}x{h} sensor "
                             f"(e.g. x={int(events['x'][i])}, y={int(events['y'][i])})")
    return events
