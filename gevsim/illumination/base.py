"""Common interface of lamp waveforms and the piecewise-linear machinery.

A waveform ``w(t)`` (``t`` in seconds) multiplies a light group's mean
radiance, so every waveform is normalised to a mean of exactly 1 over one
period (or over its table span when it is not periodic).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from gevsim import _validate
from gevsim.config import FieldError  # noqa: F401  (re-exported for the waveform modules)

__all__ = ["DC", "MAX_FREQUENCY_HZ", "RandomRanges", "Waveform", "log_uniform"]

#: The fastest lamp modulation (PWM, sinusoid) or mains frequency: 10 MHz, above any LED driver's switching
#: (hundreds of kHz to a few MHz) and far above a pixel's bandwidth (kHz). Each PWM period adds four sub-steps
#: to an emulation: frequency_hz = 1e300 asked for more than memory holds after the render.
MAX_FREQUENCY_HZ = 1e7


def real(obj: Any, name: str, **bounds: Any) -> float:
    """Check field ``name`` of ``obj`` with :func:`gevsim._validate.real` (same ``bounds``) and store it
    back as a float."""
    x = _validate.real(getattr(obj, name), name, **bounds)
    object.__setattr__(obj, name, x)
    return x


def as_time(t: Any) -> np.ndarray:
    """Return ``t`` as a float64 array (seconds)."""
    return np.asarray(t, dtype=np.float64)


class RandomRanges(Protocol):
    """What a random lamp is drawn from (a dataset's ``[dataset.randomize]``:
    :class:`gevsim.experiments.dataset.Randomize`): ``(low, high)`` pairs and the mains frequencies."""

    @property
    def frequency_hz(self) -> tuple[float, float]: ...  # log-uniform
    @property
    def duty(self) -> tuple[float, float]: ...
    @property
    def modulation(self) -> tuple[float, float]: ...
    @property
    def mains_hz(self) -> tuple[float, ...]: ...  # one of these


def log_uniform(rng: np.random.Generator, bounds: tuple[float, float]) -> float:
    """One draw, uniform in the logarithm between ``bounds`` (one ``rng.uniform`` call)."""
    from gevsim import _portable as pm

    return float(pm.exp(rng.uniform(*pm.log(bounds))))


class Waveform(ABC):
    """A lamp's relative light output as a function of time, mean 1.

    Subclasses implement ``__call__``, ``period_s`` and ``cumulative``;
    ``average`` then integrates piecewise-constant light exactly.
    """

    @abstractmethod
    def __call__(self, t: Any) -> np.ndarray:
        """Relative light output at times ``t`` (s); float64, same shape, >= 0."""

    @property
    @abstractmethod
    def period_s(self) -> float | None:
        """Period in seconds, or ``None`` when the waveform is not periodic."""

    @abstractmethod
    def cumulative(self, t: Any) -> np.ndarray:
        """Exact integral of the waveform from 0 to ``t`` (s), vectorised."""

    def integral(self, t_start: Any, t_end: Any) -> np.ndarray:
        """Exact integral of the waveform over ``[t_start, t_end]`` (broadcast)."""
        a, b = np.broadcast_arrays(as_time(t_start), as_time(t_end))
        return self.cumulative(b) - self.cumulative(a)

    def average(self, t_start: Any, t_end: Any) -> np.ndarray:
        """Mean of the waveform over each interval ``[t_start, t_end]``.

        Equals ``(C(t_end) - C(t_start)) / (t_end - t_start)``; where the
        interval is empty the value ``w(t_start)`` is returned.
        """
        a, b = np.broadcast_arrays(as_time(t_start), as_time(t_end))
        d = b - a
        empty = d == 0
        with np.errstate(invalid="ignore", divide="ignore"):
            avg = self.integral(a, b) / np.where(empty, 1.0, d)
        if np.any(empty):
            avg = np.where(empty, self(a), avg)
        return np.asarray(avg, dtype=np.float64)

    def reference_span(self) -> tuple[float, float]:
        """Interval over which the mean is 1 and flicker metrics are taken."""
        p = self.period_s
        return (0.0, 1.0) if p is None else (0.0, p)

    @property
    def mean_value(self) -> float:
        """Mean over :meth:`reference_span` (1 up to rounding), computed."""
        a, b = self.reference_span()
        return float(self.integral(a, b)) / (b - a)

    def value_range(self) -> tuple[float, float] | None:
        """Exact ``(min, max)`` over all time where cheap, else ``None``."""
        return None

    def breakpoints_s(self, t_start: float, t_end: float) -> np.ndarray:
        """Times in ``(t_start, t_end)`` where the waveform jumps or its slope changes (sorted).

        A pixel model that holds each step's mean light blurs a jump inside a step into an
        intermediate level, at which a photoreceptor whose bandwidth follows the light moves
        differently (so the answer would depend on the step and on the lamp phase); the driver
        splits steps at these times. Smooth waveforms have none."""
        return np.empty(0)

    def constant(self) -> Waveform:
        """The DC waveform of the same mean, for counterfactual no-flicker runs."""
        return DC()

    # How studies and datasets make specs of a lamp type (the fields of its config table, without
    # ``type``). A type that does not override one is not offered there
    # (:data:`gevsim.illumination.spec.SWEPT_WAVEFORMS`, :data:`~gevsim.illumination.spec.RANDOM_WAVEFORMS`).

    @classmethod
    def swept(cls, frequency_hz: float, params: Mapping[str, Any]) -> dict[str, Any]:
        """The spec fields of this lamp in a study run whose light flickers at ``frequency_hz``;
        ``params`` are the run's other sweep values (``duty``, ``modulation``)."""
        raise NotImplementedError(f"{cls.__name__} is not swept by studies")

    @classmethod
    def drawn(cls, rng: np.random.Generator, ranges: RandomRanges, *, phase_rad: float) -> dict[str, Any]:
        """The spec fields of a random lamp of this type drawn with ``rng`` from ``ranges`` (a dataset's
        sequence; ``phase_rad`` already drawn). The draws' order is part of every dataset's numbers."""
        raise NotImplementedError(f"{cls.__name__} is not drawn by datasets")


@dataclass(frozen=True)
class DC(Waveform):
    """Steady light, ``w(t) = 1``."""

    def __call__(self, t: Any) -> np.ndarray:
        return np.ones_like(as_time(t))

    @property
    def period_s(self) -> None:
        return None

    def cumulative(self, t: Any) -> np.ndarray:
        return as_time(t).copy()

    def value_range(self) -> tuple[float, float]:
        return (1.0, 1.0)

    @classmethod
    def swept(cls, frequency_hz: float, params: Mapping[str, Any]) -> dict[str, Any]:
        return {}

    @classmethod
    def drawn(cls, rng: np.random.Generator, ranges: RandomRanges, *, phase_rad: float) -> dict[str, Any]:
        return {}


class PeriodicWaveform(Waveform):
    """A periodic waveform defined by its integral over one period.

    Subclasses give ``period_s``, ``_shift_s`` (the time of phase 0) and
    ``_cum_one(r)``, the integral from phase 0 to phase ``r`` in ``[0, P]``.
    Integrals are split into whole periods plus a remainder, so averages over
    short steps stay accurate at large ``t``.
    """

    _shift_s: float = 0.0

    @abstractmethod
    def _cum_one(self, r: np.ndarray) -> np.ndarray:
        """Integral from phase 0 to ``r`` in ``[0, period_s]``."""

    @property
    def _period(self) -> float:
        p = self.period_s
        assert p is not None  # a periodic waveform has a period
        return p

    def _split(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        p = self._period
        u = t - self._shift_s
        n = np.floor(u / p)
        r = np.clip(u - n * p, 0.0, p)
        return n, r

    def _phase(self, t: np.ndarray) -> np.ndarray:
        """Time since the last phase 0, in ``[0, period_s)``."""
        r = self._split(t)[1]
        return np.where(r >= self._period, 0.0, r)

    def integral(self, t_start: Any, t_end: Any) -> np.ndarray:
        a, b = np.broadcast_arrays(as_time(t_start), as_time(t_end))
        na, ra = self._split(a)
        nb, rb = self._split(b)
        whole = float(self._cum_one(np.asarray(self._period)))
        return (nb - na) * whole + (self._cum_one(rb) - self._cum_one(ra))

    def cumulative(self, t: Any) -> np.ndarray:
        t = as_time(t)
        return self.integral(np.zeros_like(t), t)


class PiecewiseLinear:
    """Piecewise-linear function on non-decreasing knots ``x`` with values ``y``.

    Repeated knots encode jumps (the value at a repeated knot is the right
    limit). Outside ``[x[0], x[-1]]`` the end values are held.
    """

    def __init__(self, x: np.ndarray, y: np.ndarray):
        self.x = np.asarray(x, dtype=np.float64)
        self.y = np.asarray(y, dtype=np.float64)
        dx = np.diff(self.x)
        self._dx = dx
        self._slope = np.divide(np.diff(self.y), dx, out=np.zeros_like(dx), where=dx > 0)
        self._area = np.concatenate([[0.0], np.cumsum(0.5 * dx * (self.y[:-1] + self.y[1:]))])

    @property
    def total(self) -> float:
        """Integral over ``[x[0], x[-1]]``."""
        return float(self._area[-1])

    def _locate(self, u: np.ndarray) -> np.ndarray:
        i = np.searchsorted(self.x, u, side="right") - 1
        return np.clip(i, 0, len(self.x) - 2)

    def __call__(self, u: Any) -> np.ndarray:
        u = as_time(u)
        i = self._locate(u)
        v = self.y[i] + self._slope[i] * (np.clip(u, self.x[0], self.x[-1]) - self.x[i])
        return np.where(u >= self.x[-1], self.y[-1], v)

    def value_range(self) -> tuple[float, float]:
        """``(min, max)`` over the knot span; jumps count both limits."""
        live = self._dx > 0
        ends = np.concatenate([self.y[:-1][live], self.y[1:][live]])
        if ends.size == 0:
            ends = self.y
        return (float(ends.min()), float(ends.max()))

    def integral_from_start(self, u: Any) -> np.ndarray:
        """Integral from ``x[0]`` to ``u``, end values held outside the knots."""
        u = as_time(u)
        uc = np.clip(u, self.x[0], self.x[-1])
        i = self._locate(uc)
        h = uc - self.x[i]
        inside = self._area[i] + h * (self.y[i] + 0.5 * self._slope[i] * h)
        inside = np.where(uc >= self.x[-1], self._area[-1], inside)
        before = np.minimum(u - self.x[0], 0.0) * self.y[0]
        after = np.maximum(u - self.x[-1], 0.0) * self.y[-1]
        return inside + before + after
