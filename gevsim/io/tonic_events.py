"""Events as tonic's transforms expect them (tonic: Lenz, Chaney, Shrestha et al., 2021).

tonic's ``ToFrame`` counts each event into channel ``p`` (an integer index into the
channels of ``sensor_size = (W, H, P)``), and ``ToVoxelGrid`` needs ``P = 2`` and turns
``p == 0`` into -1 by assigning -1 into the ``p`` field (tonic 1.7,
``tonic/functional/to_voxel_grid.py``): a bool ``p`` becomes True, so OFF events count
+1, and a gradient event's ``axis`` is not looked at, so both axes land in one channel.

:func:`to_tonic` gives every gevsim stream a signed integer channel index ``p``:

- brightness events (DVS, CSDVS): ``p`` = 0 OFF, 1 ON (2 channels, :data:`BRIGHTNESS_CHANNELS`);
- gradient events: ``p`` = 2 axis + (sign > 0): 0 X-, 1 X+, 2 Y-, 3 Y+ (4 channels,
  :data:`GRADIENT_CHANNELS`), or, with ``axis=`` 0 (X) or 1 (Y), that axis alone with
  ``p`` = 0 for -1, 1 for +1 (2 channels: what ``ToVoxelGrid`` accepts).

:func:`sensor_size` gives the matching ``(W, H, P)``. The arrays are new (tonic's
transforms write into ``p``), with the fields ``x``, ``y`` (int16), ``t`` (int64,
microseconds) and ``p`` (int8).
"""

from __future__ import annotations

import numpy as np

from gevsim._validate import size
from gevsim.events.types import AXIS_X, AXIS_Y, check_events, is_gradient

#: Channel names of brightness events, by tonic channel index.
BRIGHTNESS_CHANNELS = ("off", "on")
#: Channel names of gradient events (all axes), by tonic channel index.
GRADIENT_CHANNELS = ("x-", "x+", "y-", "y+")
#: dtype of :func:`to_tonic`'s output.
TONIC_DTYPE = np.dtype([("x", "<i2"), ("y", "<i2"), ("t", "<i8"), ("p", "i1")])

__all__ = ["BRIGHTNESS_CHANNELS", "GRADIENT_CHANNELS", "TONIC_DTYPE", "sensor_size", "to_tonic"]


def _check_axis(axis, gradient: bool) -> int | None:
    if axis is None:
        return None
    if not gradient:
        raise ValueError(f"axis={axis!r} applies to gradient events only; brightness events have no axis")
    if isinstance(axis, bool) or axis not in (AXIS_X, AXIS_Y):
        raise ValueError(f"axis must be None (both axes), {AXIS_X} (X) or {AXIS_Y} (Y), got {axis!r}")
    return int(axis)


def to_tonic(events: np.ndarray, *, axis: int | None = None) -> np.ndarray:
    """gevsim events (BRIGHTNESS_DTYPE or GRADIENT_DTYPE) as tonic events: ``p`` is the channel.

    Parameters
    ----------
    events : a gevsim event array (e.g. ``EventReader.read(stream)``), time-sorted.
    axis : gradient events only: None for the 4 channels (axis, sign), or 0 (X) / 1 (Y) for the
        events of that axis with the 2 channels of their sign (1 = upward step, as a DVS ON event).
        Polarity augmentations need one axis at a time: tonic's ``RandomFlipPolarity`` inverts ``p``
        as a bool, which negates a brightness or one-axis stream exactly but sends every event of
        the 4-channel layout's Y channels to channel 0 (tested).

    Returns
    -------
    A new :data:`TONIC_DTYPE` array, in the order of ``events``.
    """
    check_events(events)
    gradient = is_gradient(events)
    axis = _check_axis(axis, gradient)
    if axis is not None:
        events = events[events["axis"] == axis]
    out = np.empty(len(events), TONIC_DTYPE)
    out["x"], out["y"], out["t"] = events["x"], events["y"], events["t"]
    if not gradient:
        out["p"] = events["p"]  # True (ON) -> 1, False (OFF) -> 0
        return out
    p = events["p"]
    if len(p) and np.any(p == 0):
        raise ValueError(f"gradient events must have p = +1 or -1; {int(np.count_nonzero(p == 0))} have p = 0")
    positive = (p > 0).astype(np.int8)
    out["p"] = positive if axis is not None else 2 * events["axis"].astype(np.int8) + positive
    return out


def sensor_size(width: int, height: int, events: np.ndarray | np.dtype, *, axis: int | None = None
                ) -> tuple[int, int, int]:
    """tonic's ``sensor_size`` ``(W, H, P)`` for :func:`to_tonic` of ``events`` (an event array or
    its dtype) with the same ``axis``: P = 2 for brightness events and for one gradient axis, 4
    for both gradient axes."""
    w, h = size(width, height)
    dtype = events if isinstance(events, np.dtype) else getattr(events, "dtype", None)
    if dtype is None or dtype.names is None:
        raise TypeError(f"events must be a gevsim event array or its dtype, got {type(events).__name__}")
    check_events(np.zeros(0, dtype))
    gradient = "axis" in dtype.names
    axis = _check_axis(axis, gradient)
    return (w, h, len(GRADIENT_CHANNELS) if gradient and axis is None else len(BRIGHTNESS_CHANNELS))
