"""Checks shared by every stage that consumes a chunk of samples over time."""

from __future__ import annotations

import numpy as np

from gevsim._validate import real_array


def check_chunk(values, t_s, *, shape, name: str, after: float | None):
    """Validate a chunk of samples ``values`` (T, H, W) at strictly increasing times
    ``t_s`` (T,), all later than ``after`` (None: no earlier sample).

    Returns (values as a float array, t (T,), prev (T,)) where ``prev[k]`` is the
    time of the sample before ``t[k]`` (``-inf`` for the very first one).
    """
    v = np.asarray(values)
    t = np.asarray(t_s, dtype=np.float64).reshape(-1)
    if v.ndim != 3 or v.shape[1:] != tuple(shape):
        raise ValueError(f"{name} must have shape (T, {shape[0]}, {shape[1]}), got {v.shape}")
    if len(t) != v.shape[0]:
        raise ValueError(f"t_s has {len(t)} times but {name} has {v.shape[0]} samples")
    if v.dtype.kind != "f":
        v = v.astype(np.float64)
    real_array(t, "t_s")
    prev = np.concatenate([[-np.inf if after is None else after], t[:-1]]) if len(t) else t
    if np.any(t <= prev):
        k = int(np.argmax(t <= prev))
        raise ValueError(f"time must increase strictly: sample {k} at t = {t[k]!r} s follows {prev[k]!r} s")
    return np.ascontiguousarray(v), t, prev
