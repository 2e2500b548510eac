"""Mains-powered lamps: fluorescent, incandescent and high-pressure sodium.

The electrical power of a lamp on mains of frequency ``f`` goes as
``sin^2(2 pi f t) = (1 - cos(4 pi f t)) / 2``; the light output is modelled
as that power through a first-order low-pass of time constant ``tau``
(phosphor persistence, or filament thermal inertia). The periodic steady state
is ``w = 1 - a cos(4 pi f t - phi)`` with ``a = 1 / sqrt(1 + (4 pi f tau)^2)``
and ``phi = atan(4 pi f tau)``; ``a`` is the percent flicker / 100.

Default time constants are assumptions tuned to typical magnetic-ballast
figures (IEEE Std 1789-2015, Annex; Lehman & Wilkins 2014, "Designing to
mitigate effects of flicker in LED lighting", IEEE Power Electron. Mag. 1(3)):
fluorescent ~30 % flicker, incandescent 60-100 W ~10 %, HPS ~95 %.
"""

from __future__ import annotations

import math
from abc import abstractmethod
from collections.abc import Mapping
from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np

from .base import MAX_FREQUENCY_HZ, FieldError, RandomRanges, Waveform, real
from .basic import Sinusoid
from .table import Table

__all__ = ["MainsLamp", "Fluorescent", "Incandescent", "SodiumHID"]

#: Phosphor persistence giving ~30 % flicker at 50 Hz (26 % at 60 Hz); assumed.
FLUORESCENT_PERSISTENCE_S = 5.0e-3
#: Effective filament time constant giving ~10 % flicker at 50 Hz (8 % at 60 Hz); assumed.
INCANDESCENT_TIME_CONSTANT_S = 16.0e-3
#: HPS dark fraction of each half cycle around the current zero; assumed.
SODIUM_REIGNITION_FRACTION = 0.15
#: HPS radiative persistence; assumed: ~95 % flicker, flicker index ~0.3 at 50 Hz (~91 % at 60 Hz).
SODIUM_PERSISTENCE_S = 0.7e-3


def first_order_response(mains_hz: float, tau_s: float) -> tuple[float, float]:
    """Return ``(a, phi)`` of the low-passed ``sin^2`` drive at ``2 mains_hz``."""
    from gevsim import _portable as pm

    x = 4.0 * math.pi * mains_hz * tau_s
    return 1.0 / math.sqrt(1.0 + x * x), float(pm.atan(x))


class MainsLamp(Waveform):
    """Base of mains-driven lamps: delegates to an exact inner waveform.

    The light period is half the mains period. ``phase_rad`` is the phase of
    the mains voltage at ``t = 0`` (e.g. ``2 pi / 3`` for another phase of a
    three-phase supply).
    """

    mains_hz: float
    phase_rad: float

    @property
    @abstractmethod
    def _inner(self) -> Waveform: ...

    @property
    def period_s(self) -> float:
        return 0.5 / self.mains_hz

    def __call__(self, t: Any) -> np.ndarray:
        return self._inner(t)

    def cumulative(self, t: Any) -> np.ndarray:
        return self._inner.cumulative(t)

    def integral(self, t_start: Any, t_end: Any) -> np.ndarray:
        return self._inner.integral(t_start, t_end)

    def value_range(self) -> tuple[float, float] | None:
        return self._inner.value_range()

    @classmethod
    def swept(cls, frequency_hz: float, params: Mapping[str, Any]) -> dict[str, Any]:
        """The light flickers at twice the mains frequency."""
        return {"mains_hz": frequency_hz / 2}

    @classmethod
    def drawn(cls, rng: np.random.Generator, ranges: RandomRanges, *, phase_rad: float) -> dict[str, Any]:
        return {"mains_hz": float(ranges.mains_hz[int(rng.integers(len(ranges.mains_hz)))]), "phase_rad": phase_rad}


class _FirstOrderLamp(MainsLamp):
    @property
    @abstractmethod
    def depth(self) -> float:
        """Modulation depth ``a`` (percent flicker / 100)."""

    @property
    @abstractmethod
    def lag_rad(self) -> float:
        """Phase lag ``phi`` of the light behind the electrical power."""

    @cached_property
    def _inner(self) -> Sinusoid:
        # 1 - a cos(2 w t + 2 phase - phi) = 1 + a sin(2 w t + 2 phase - phi - pi / 2)
        return Sinusoid(2.0 * self.mains_hz, self.depth, 2.0 * self.phase_rad - self.lag_rad - 0.5 * math.pi)


@dataclass(frozen=True)
class Fluorescent(_FirstOrderLamp):
    """Fluorescent tube on a magnetic ballast (phosphor persistence low-pass).

    Give either ``persistence_s`` (default ``FLUORESCENT_PERSISTENCE_S``,
    assumed) or ``modulation`` (the depth ``a`` in ``[0, 1]``) directly.
    """

    mains_hz: float = 50.0
    persistence_s: float | None = None
    modulation: float | None = None
    phase_rad: float = 0.0

    def __post_init__(self) -> None:
        real(self, "mains_hz", low=0.0, low_open=True, high=MAX_FREQUENCY_HZ)
        real(self, "phase_rad")
        if self.persistence_s is not None and self.modulation is not None:
            raise FieldError("modulation", "give persistence_s or modulation, not both "
                             f"(persistence_s={self.persistence_s!r}, modulation={self.modulation!r})")
        if self.persistence_s is not None:
            real(self, "persistence_s", low=0.0)
        if self.modulation is not None:
            real(self, "modulation", low=0.0, high=1.0)

    @classmethod
    def swept(cls, frequency_hz: float, params: Mapping[str, Any]) -> dict[str, Any]:
        spec = super().swept(frequency_hz, params)
        return {**spec, "modulation": float(params["modulation"])} if "modulation" in params else spec

    @property
    def depth(self) -> float:
        if self.modulation is not None:
            return self.modulation
        tau = FLUORESCENT_PERSISTENCE_S if self.persistence_s is None else self.persistence_s
        return first_order_response(self.mains_hz, tau)[0]

    @property
    def lag_rad(self) -> float:
        if self.modulation is not None:
            from gevsim import _portable as pm

            a = self.modulation
            return 0.5 * math.pi if a == 0 else float(pm.atan(math.sqrt(max(1.0 / (a * a) - 1.0, 0.0))))
        tau = FLUORESCENT_PERSISTENCE_S if self.persistence_s is None else self.persistence_s
        return first_order_response(self.mains_hz, tau)[1]


@dataclass(frozen=True)
class Incandescent(_FirstOrderLamp):
    """Incandescent lamp; ``thermal_time_constant_s`` is an effective value.

    The default (assumed) gives ~10 % flicker at 50 Hz, typical of 60-100 W
    lamps (IEEE Std 1789-2015 survey figures); it lumps the filament's
    thermal inertia and the steep light-versus-temperature law.
    """

    mains_hz: float = 50.0
    thermal_time_constant_s: float = INCANDESCENT_TIME_CONSTANT_S
    phase_rad: float = 0.0

    def __post_init__(self) -> None:
        real(self, "mains_hz", low=0.0, low_open=True, high=MAX_FREQUENCY_HZ)
        real(self, "thermal_time_constant_s", low=0.0)
        real(self, "phase_rad")

    @property
    def depth(self) -> float:
        return first_order_response(self.mains_hz, self.thermal_time_constant_s)[0]

    @property
    def lag_rad(self) -> float:
        return first_order_response(self.mains_hz, self.thermal_time_constant_s)[1]


@dataclass(frozen=True)
class SodiumHID(MainsLamp):
    """High-pressure sodium lamp: ``sin^2`` power with a dark reignition band.

    The arc is out for ``reignition_fraction`` of each half cycle, centred on
    the current zero; the drive then passes through a first-order low-pass
    (``persistence_s``) solved exactly for its periodic steady state on a
    fine grid (drive linear between grid points) and tabulated.
    """

    mains_hz: float = 50.0
    reignition_fraction: float = SODIUM_REIGNITION_FRACTION
    persistence_s: float = SODIUM_PERSISTENCE_S
    phase_rad: float = 0.0

    #: grid segments in the lit part and in the dark band of one light period
    _N_ON = 2048
    _N_DARK = 128

    def __post_init__(self) -> None:
        real(self, "mains_hz", low=0.0, low_open=True, high=MAX_FREQUENCY_HZ)
        real(self, "reignition_fraction", low=0.0, high=1.0, high_open=True)
        real(self, "persistence_s", low=0.0)
        real(self, "phase_rad")

    @cached_property
    def _inner(self) -> Table:
        from gevsim import _portable as pm

        p = self.period_s
        half = 0.5 * self.reignition_fraction * p
        # times from the current zero: dark band [-half, half], lit (half, p - half)
        dark = np.linspace(-half, half, self._N_DARK + 1)
        lit = np.linspace(half, p - half, self._N_ON + 1)
        x = np.concatenate([dark, lit[1:]])
        drive = np.square(pm.sin(math.pi * x / p))
        p0 = np.concatenate([np.zeros(self._N_DARK), drive[self._N_DARK:-1]])
        p1 = np.concatenate([np.zeros(self._N_DARK), drive[self._N_DARK + 1:]])
        if half == 0.0:  # no dark band: drop its zero-length segments
            x, p0, p1 = x[self._N_DARK:], p0[self._N_DARK:], p1[self._N_DARK:]
        y = _periodic_first_order(np.diff(x), p0, p1, self.persistence_s)
        t0 = x - self.phase_rad / (2.0 * math.pi * self.mains_hz)
        return Table(tuple(t0), tuple(y), periodic=True)


def _periodic_first_order(h: np.ndarray, p0: np.ndarray, p1: np.ndarray, tau: float) -> np.ndarray:
    """Periodic steady state of ``tau y' = p - y`` at the grid nodes.

    ``p`` is linear from ``p0[k]`` to ``p1[k]`` over segment ``k`` of length
    ``h[k]``; the segment update ``y1 = E y0 + c`` is exact.
    """
    if tau == 0.0:
        return np.concatenate([[p1[-1]], p1])
    from gevsim import _portable as pm

    e = pm.exp(-h / tau)
    s_tau = (p1 - p0) / h * tau
    c = p1 - s_tau + (s_tau - p0) * e
    y = np.empty(h.size + 1)
    y[0] = 0.0
    for k in range(h.size):
        y[k + 1] = e[k] * y[k] + c[k]
    y0 = y[-1] / -float(pm.expm1(-float(h.sum()) / tau))  # fixed point of the one-period map
    y[0] = y0
    for k in range(h.size):
        y[k + 1] = e[k] * y[k] + c[k]
    return np.maximum(y, 0.0)
