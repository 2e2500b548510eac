"""Input checks shared by the optics modules (private)."""

from __future__ import annotations

import math

import numpy as np


def positive_number(value, *, name: str, upper: float | None = None) -> float:
    """Return ``value`` as a float if it is finite, > 0 (and <= ``upper``)."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise TypeError(f"{name} must be a real number, got {value!r}")
    value = float(value)
    if not math.isfinite(value) or value <= 0.0:
        raise ValueError(f"{name} must be finite and > 0, got {value!r}")
    if upper is not None and value > upper:
        raise ValueError(f"{name} must be in (0, {upper:g}], got {value!r}")
    return value


def finite_nonnegative(array, *, name: str) -> np.ndarray:
    """Return ``array`` as a float ndarray; raise if any value is non-finite or < 0."""
    arr = np.asarray(array)
    if arr.dtype.kind not in "biuf":
        raise TypeError(f"{name} must be a real numeric array, got dtype {arr.dtype}")
    if arr.dtype.kind != "f":
        arr = arr.astype(np.float64)
    finite = np.isfinite(arr)
    n_bad = int(arr.size - np.count_nonzero(finite))
    if n_bad:
        raise ValueError(f"{name} has {n_bad} non-finite value(s) (NaN or inf) out of {arr.size}")
    n_neg = int(np.count_nonzero(arr < 0))
    if n_neg:
        raise ValueError(
            f"{name} has {n_neg} negative value(s) out of {arr.size} (min {float(arr.min())!r}); "
            "radiometric quantities must be >= 0"
        )
    return arr
