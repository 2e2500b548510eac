"""Input checks shared by every stage (private; in the style of scikit-image's ``_shared/utils``).

Each check returns the value converted (a float, an int, an array) or raises an
error whose message names the parameter and the value it got. Errors are
:class:`FieldError` (a ``ValueError`` that carries the parameter's name, so a
dataclass built from a TOML table reports the key: :class:`gevsim.config.FromTable`);
a value of the wrong type raises :class:`FieldTypeError`, which is also a ``TypeError``.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

__all__ = ["FieldError", "FieldTypeError", "increasing", "integer", "real", "real_array", "real_list", "size"]


class FieldError(ValueError):
    """A bad value of the parameter (or dataclass field) ``field``."""

    def __init__(self, field: str, message: str):
        self.field = field
        super().__init__(message)


class FieldTypeError(FieldError, TypeError):
    """A value of the wrong type for the parameter ``field``."""


_REALS = (int, float, np.integer, np.floating)


def _is_real(value: Any) -> bool:
    return isinstance(value, _REALS) and not isinstance(value, (bool, np.bool_))


def _interval(low: float | None, high: float | None, low_open: bool, high_open: bool) -> str:
    if low is not None and high is not None:
        return f"in {'(' if low_open else '['}{low:g}, {high:g}{')' if high_open else ']'}"
    if low is not None:
        return f"{'>' if low_open else '>='} {low:g}"
    if high is not None:
        return f"{'<' if high_open else '<='} {high:g}"
    return ""


def real(value: Any, name: str, *, low: float | None = None, high: float | None = None, low_open: bool = False,
         high_open: bool = False, allow_inf: bool = False) -> float:
    """``value`` as a float, finite (unless ``allow_inf``) and within the bounds.

    ``low_open`` / ``high_open`` exclude the bound itself: ``real(x, "gain", low=0, low_open=True)``
    requires ``x > 0``.
    """
    interval = _interval(low, high, low_open, high_open)
    wanted = ("finite" if not allow_inf else "a number") + (f" and {interval}" if interval else "")
    if isinstance(value, np.ndarray) and value.ndim == 0 and value.dtype.kind in "iuf":
        value = value.item()
    if not _is_real(value):
        raise FieldTypeError(name, f"{name} must be a real number, got {value!r}")
    if isinstance(value, int) and abs(value) > 1 << 53:  # compiled kernels take int64: 2^63 overflowed there
        raise FieldError(name, f"{name} must be {wanted}, got the integer {value!r} (beyond 2^53; write a float)")
    x = float(value)
    if math.isnan(x) or (math.isinf(x) and not allow_inf):
        raise FieldError(name, f"{name} must be {wanted}, got {value!r}")
    if low is not None and (x < low or (low_open and x == low)):
        raise FieldError(name, f"{name} must be {wanted}, got {value!r}")
    if high is not None and (x > high or (high_open and x == high)):
        raise FieldError(name, f"{name} must be {wanted}, got {value!r}")
    return x


def integer(value: Any, name: str, *, low: int | None = None, high: int | None = None) -> int:
    """``value`` as an int (a Python or NumPy integer, not a bool) within ``low..high``."""
    if low == 1 and high is None:
        wanted = "a positive integer"
    elif low is not None and high is not None:
        wanted = f"an integer in {low}..{high}"
    else:
        wanted = f"an integer {_interval(low, high, False, False)}".rstrip()
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise FieldTypeError(name, f"{name} must be {wanted}, got {value!r}")
    if (low is not None and value < low) or (high is not None and value > high):
        raise FieldError(name, f"{name} must be {wanted}, got {value!r}")
    return int(value)


def size(width: Any, height: Any) -> tuple[int, int]:
    """``(width, height)`` of an image in pixels, both positive integers."""
    return integer(width, "width", low=1), integer(height, "height", low=1)


def real_list(values: Any, name: str, *, positive: bool = False) -> tuple[float, ...]:
    """A non-empty list (or 1-D array) of finite numbers (each > 0 when ``positive``), as a tuple of floats."""
    wanted = f"a non-empty list of {'positive' if positive else 'finite'} numbers"
    items = list(values) if isinstance(values, (list, tuple, np.ndarray)) else None
    if not items or not all(_is_real(v) and math.isfinite(v) and (v > 0 or not positive) for v in items):
        raise FieldError(name, f"{name} must be {wanted}, got {values!r}")
    return tuple(float(v) for v in items)


#: Arrays of at least this many values are checked by :mod:`gevsim._finite` (parallel, no temporaries).
_PARALLEL_SIZE = 1 << 16


def real_array(values: Any, name: str, *, nonnegative: bool = False, dtype: Any = None) -> np.ndarray:
    """``values`` as a real array with every value finite (and >= 0 when ``nonnegative``).

    Float arrays keep their dtype unless ``dtype`` is given; others become float64.
    """
    arr = np.asarray(values)
    if arr.dtype.kind not in "biuf":
        raise FieldTypeError(name, f"{name} must be a real numeric array, got dtype {arr.dtype}")
    if dtype is not None:
        arr = arr.astype(dtype, copy=False)
    elif arr.dtype.kind != "f":
        arr = arr.astype(np.float64)
    if arr.size >= _PARALLEL_SIZE:  # counted on all cores first; the message needs numpy's mask
        from gevsim._finite import count_invalid
        if count_invalid(arr, nonnegative=nonnegative) == 0:
            return arr
    bad = ~np.isfinite(arr)
    if bad.any():
        raise FieldError(name, f"{name} has {int(bad.sum())} non-finite value(s) (NaN or inf) out of {arr.size}"
                               f"{_first(arr, bad, name)}")
    if nonnegative:
        bad = arr < 0
        if bad.any():
            raise FieldError(name, f"{name} has {int(bad.sum())} negative value(s) out of {arr.size} "
                                   f"(min {float(arr.min())!r}){_first(arr, bad, name)}; it must be >= 0")
    return arr


def _first(arr: np.ndarray, bad: np.ndarray, name: str) -> str:
    """``", first name[i, j] = value"`` for the first ``bad`` element (nothing for a 0-d array)."""
    if arr.ndim == 0:
        return f", got {arr.item()!r}"
    index = np.unravel_index(int(np.argmax(bad)), arr.shape)
    return f", first {name}[{', '.join(str(int(i)) for i in index)}] = {arr[index].item()!r}"


def increasing(times: Any, name: str, *, what: str = "sample", unit: str = "s") -> np.ndarray:
    """``times`` as a non-empty 1-D array of finite, strictly increasing numbers (its dtype kept).

    ``what`` and ``unit`` word the error: "t_s must increase strictly: frame 2 at 0.1 s follows 0.2 s".
    """
    t = np.asarray(times)
    if t.dtype.kind not in "iuf":
        raise FieldTypeError(name, f"{name} must be numeric times in {unit}, got dtype {t.dtype}")
    if t.ndim != 1 or t.size == 0:
        raise FieldError(name, f"{name} must be a non-empty 1-D array of times in {unit}, got shape {t.shape}")
    n_bad = int(t.size - np.count_nonzero(np.isfinite(t)))
    if n_bad:
        raise FieldError(name, f"{name} must be finite: {n_bad} of {t.size} values are NaN or infinite")
    bad = np.flatnonzero(np.diff(t) <= 0)
    if len(bad):
        k = int(bad[0]) + 1
        raise FieldError(name, f"{name} must increase strictly: {what} {k} at {t[k].item()!r} {unit} "
                               f"follows {t[k - 1].item()!r} {unit}")
    return t
