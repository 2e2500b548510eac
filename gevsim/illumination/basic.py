"""Elementary lamp waveforms: DC, sinusoidal and PWM (LED dimmer) light."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np

from .base import (
    DC,
    MAX_FREQUENCY_HZ,
    FieldError,
    PeriodicWaveform,
    PiecewiseLinear,
    RandomRanges,
    as_time,
    log_uniform,
    real,
)

__all__ = ["DC", "Sinusoid", "PWM"]  # DC lives beside Waveform (Waveform.constant makes one)


@dataclass(frozen=True)
class Sinusoid(PeriodicWaveform):
    """Sinusoidally modulated light, ``w(t) = 1 + m sin(2 pi f t + phi)``.

    Parameters
    ----------
    frequency_hz : float
        Modulation frequency ``f`` (> 0).
    modulation : float
        Modulation depth ``m`` in ``[0, 1]``; percent flicker is ``100 m``.
    phase_rad : float
        Phase ``phi`` at ``t = 0``.
    """

    frequency_hz: float
    modulation: float = 1.0
    phase_rad: float = 0.0

    def __post_init__(self) -> None:
        real(self, "frequency_hz", low=0.0, low_open=True, high=MAX_FREQUENCY_HZ)
        real(self, "modulation", low=0.0, high=1.0)
        real(self, "phase_rad")

    @property
    def period_s(self) -> float:
        return 1.0 / self.frequency_hz

    @property
    def _omega(self) -> float:
        return 2.0 * math.pi * self.frequency_hz

    def __call__(self, t: Any) -> np.ndarray:
        from gevsim import _portable as pm

        t = as_time(t)
        r = self._phase(t)  # phase reduction keeps sin() accurate at large t
        return np.maximum(1.0 + self.modulation * pm.sin(self._omega * r + self.phase_rad), 0.0)

    def _cum_one(self, r: np.ndarray) -> np.ndarray:
        from gevsim import _portable as pm

        w, phi = self._omega, self.phase_rad
        return r - (self.modulation / w) * (pm.cos(w * r + phi) - pm.cos(phi))

    def value_range(self) -> tuple[float, float]:
        return (1.0 - self.modulation, 1.0 + self.modulation)

    @classmethod
    def swept(cls, frequency_hz: float, params: Mapping[str, Any]) -> dict[str, Any]:
        return {"frequency_hz": frequency_hz, "modulation": float(params.get("modulation", 1.0))}

    @classmethod
    def drawn(cls, rng: np.random.Generator, ranges: RandomRanges, *, phase_rad: float) -> dict[str, Any]:
        f = log_uniform(rng, ranges.frequency_hz)
        return {"frequency_hz": f, "modulation": float(rng.uniform(*ranges.modulation)), "phase_rad": phase_rad}


@dataclass(frozen=True)
class PWM(PeriodicWaveform):
    """Trapezoidal pulse train of a PWM-dimmed LED, scaled to mean 1.

    Each period starts (at ``phase_s``) with a linear rise of ``rise_s`` from
    ``low_level`` to the peak, holds the peak, falls linearly in ``fall_s``
    and stays at ``low_level`` for the rest of the period.

    Parameters
    ----------
    frequency_hz : float
        PWM frequency (> 0).
    duty : float
        Fraction of the period at or above half level, in ``(0, 1]``: the
        plateau plus half of each edge.
    rise_s, fall_s : float
        Edge durations (>= 0); they must fit in the period with the duty.
    phase_s : float
        Time at which a rising edge starts.
    low_level : float
        Off level as a fraction of the peak, in ``[0, 1]`` (0: fully off).
    """

    frequency_hz: float
    duty: float
    rise_s: float = 0.0
    fall_s: float = 0.0
    phase_s: float = 0.0
    low_level: float = 0.0

    def __post_init__(self) -> None:
        f = real(self, "frequency_hz", low=0.0, low_open=True, high=MAX_FREQUENCY_HZ)
        d = real(self, "duty", low=0.0, high=1.0, low_open=True)
        r = real(self, "rise_s", low=0.0)
        g = real(self, "fall_s", low=0.0)
        real(self, "phase_s")
        real(self, "low_level", low=0.0, high=1.0)
        p = 1.0 / f
        edges = 0.5 * (r + g)
        if edges > d * p * (1 + 1e-12) or d * p + edges > p * (1 + 1e-12):
            field = "rise_s" if r >= g else "fall_s"
            raise FieldError(
                field,
                f"rise_s={r!r} and fall_s={g!r} do not fit a period of {p!r} s with duty={d!r}: "
                "need (rise_s + fall_s) / 2 <= duty * period <= period - (rise_s + fall_s) / 2",
            )

    @property
    def period_s(self) -> float:
        return 1.0 / self.frequency_hz

    @property
    def _shift_s(self) -> float:  # type: ignore[override]
        return self.phase_s

    @cached_property
    def _shape(self) -> PiecewiseLinear:
        p, r, g, lo = self.period_s, self.rise_s, self.fall_s, self.low_level
        plateau = max(self.duty * p - 0.5 * (r + g), 0.0)
        x1 = min(r, p)
        x2 = min(x1 + plateau, p)
        x3 = min(x2 + g, p)
        scale = 1.0 / (lo + (1.0 - lo) * self.duty)
        x = np.array([0.0, x1, x2, x3, p])
        y = np.array([lo, 1.0, 1.0, lo, lo]) * scale
        return PiecewiseLinear(x, y)

    def __call__(self, t: Any) -> np.ndarray:
        return self._shape(self._phase(as_time(t)))

    def breakpoints_s(self, t_start: float, t_end: float) -> np.ndarray:
        """The corners of each period's trapezoid (rise start, peak, fall start, fall end)."""
        p = self.period_s
        corners = np.unique(self._shape.x[:-1])
        k0 = math.floor((t_start - self.phase_s) / p)
        k1 = math.floor((t_end - self.phase_s) / p)
        t = (self.phase_s + p * np.arange(k0, k1 + 1)[:, None] + corners[None, :]).ravel()
        return np.unique(t[(t > t_start) & (t < t_end)])

    def _cum_one(self, r: np.ndarray) -> np.ndarray:
        return self._shape.integral_from_start(r)

    def value_range(self) -> tuple[float, float]:
        return self._shape.value_range()

    @classmethod
    def swept(cls, frequency_hz: float, params: Mapping[str, Any]) -> dict[str, Any]:
        return {"frequency_hz": frequency_hz, "duty": float(params.get("duty", 0.5))}

    @classmethod
    def drawn(cls, rng: np.random.Generator, ranges: RandomRanges, *, phase_rad: float) -> dict[str, Any]:
        f = log_uniform(rng, ranges.frequency_hz)
        duty = float(rng.uniform(*ranges.duty))
        return {"frequency_hz": f, "duty": duty, "phase_s": phase_rad / (2.0 * math.pi * f)}
