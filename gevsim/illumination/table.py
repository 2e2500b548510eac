"""Tabulated (measured) lamp waveforms, linearly interpolated."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np

from gevsim._validate import increasing, real_array

from .base import FieldError, PeriodicWaveform, PiecewiseLinear, as_time

__all__ = ["Table"]


@dataclass(frozen=True)
class Table(PeriodicWaveform):
    """User-supplied light samples, linearly interpolated, scaled to mean 1.

    Parameters
    ----------
    times_s : sequence of float
        Strictly increasing, finite sample times (at least two).
    values : sequence of float
        Finite, non-negative relative light output, not all zero; any
        scale (the table is normalised to mean 1 over its span).
    periodic : bool
        If true the table repeats with period ``times_s[-1] - times_s[0]``:
        the last sample is followed by the first one of the next period
        (a jump when their values differ). If false the end values are held
        outside the span.

    Notes
    -----
    ``times_s`` and ``values`` are stored as tuples of float (hashable).
    """

    times_s: tuple[float, ...]
    values: tuple[float, ...]
    periodic: bool = False

    def __post_init__(self) -> None:
        t = _vector(self.times_s, "times_s")
        v = _vector(self.values, "values")
        if t.size < 2:
            raise FieldError("times_s", f"times_s needs at least 2 samples, got {t.size}")
        if v.shape != t.shape:
            raise FieldError("values", f"values has {v.size} samples but times_s has {t.size}")
        increasing(t, "times_s", what="entry")
        real_array(v, "values", nonnegative=True)
        if not isinstance(self.periodic, (bool, np.bool_)):
            raise FieldError("periodic", f"periodic={self.periodic!r} must be true or false")
        area = PiecewiseLinear(t, v).total
        if not area > 0:
            raise FieldError("values", f"values have zero mean over the span (values={v.tolist()!r})")
        object.__setattr__(self, "times_s", tuple(t.tolist()))
        object.__setattr__(self, "values", tuple(v.tolist()))
        object.__setattr__(self, "periodic", bool(self.periodic))

    @cached_property
    def _shape(self) -> PiecewiseLinear:
        t = np.asarray(self.times_s)
        v = np.asarray(self.values)
        raw = PiecewiseLinear(t - t[0], v)
        return PiecewiseLinear(t - t[0], v * ((t[-1] - t[0]) / raw.total))

    @property
    def span_s(self) -> float:
        """Duration covered by the samples."""
        return self.times_s[-1] - self.times_s[0]

    @property
    def period_s(self) -> float | None:
        return self.span_s if self.periodic else None

    @property
    def _shift_s(self) -> float:  # type: ignore[override]
        return self.times_s[0]

    def reference_span(self) -> tuple[float, float]:
        return (self.times_s[0], self.times_s[-1])

    def __call__(self, t: Any) -> np.ndarray:
        t = as_time(t)
        u = self._phase(t) if self.periodic else t - self.times_s[0]
        return self._shape(u)

    def _cum_one(self, r: np.ndarray) -> np.ndarray:
        return self._shape.integral_from_start(r)

    def integral(self, t_start: Any, t_end: Any) -> np.ndarray:
        if self.periodic:
            return super().integral(t_start, t_end)
        a, b = np.broadcast_arrays(as_time(t_start), as_time(t_end))
        f = self._shape.integral_from_start
        t0 = self.times_s[0]
        return f(b - t0) - f(a - t0)

    def value_range(self) -> tuple[float, float]:
        return self._shape.value_range()


def _vector(seq: Any, name: str) -> np.ndarray:
    try:
        arr = np.asarray(seq, dtype=np.float64)
    except (TypeError, ValueError):
        raise FieldError(name, f"{name}={seq!r} must be a sequence of real numbers") from None
    if arr.ndim != 1:
        raise FieldError(name, f"{name} must be one-dimensional, got shape {arr.shape}")
    return real_array(arr, name)
