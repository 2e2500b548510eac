"""1/f (flicker) voltage noise at the output: Ornstein-Uhlenbeck processes, one pole per decade
with equal variance, whose sum has a 1/f spectrum between two corners (McWhorter's construction)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from gevsim._validate import FieldError, real
from gevsim.pixel.mechanisms._base import MAX_NOISE_V, KernelNoise


@dataclass(frozen=True)
class FlickerNoise:
    """flicker_noise_v : rms of the 1/f voltage noise (0: off) between ``flicker_noise_low_hz`` and
    ``flicker_noise_high_hz``."""

    flicker_noise_v: float = 0.0
    flicker_noise_low_hz: float = 1.0
    flicker_noise_high_hz: float = 1000.0

    def __post_init__(self):
        real(self.flicker_noise_v, "flicker_noise_v", low=0, high=MAX_NOISE_V)
        real(self.flicker_noise_low_hz, "flicker_noise_low_hz", low=0, low_open=True)
        real(self.flicker_noise_high_hz, "flicker_noise_high_hz", low=0, low_open=True)
        if self.flicker_noise_high_hz <= self.flicker_noise_low_hz:
            raise FieldError("flicker_noise_high_hz", f"{type(self).__name__}.flicker_noise_high_hz must exceed "
                             f"flicker_noise_low_hz, got {self.flicker_noise_high_hz!r} <= "
                             f"{self.flicker_noise_low_hz!r}")


def flicker_noise_poles(noise: Any, volts_per_ln: float) -> tuple[np.ndarray, np.ndarray]:
    """Corner frequencies and variances of Ornstein-Uhlenbeck processes whose sum has
    a 1/f spectrum between the two corners (one pole per decade, equal variance:
    McWhorter's construction); total variance = (flicker_noise_v / n U_T)^2."""
    if noise.flicker_noise_v == 0:
        return np.zeros(0), np.zeros(0)
    from gevsim import _portable as pm

    lo, hi = noise.flicker_noise_low_hz, noise.flicker_noise_high_hz
    decades = float(pm.log10(hi / lo))
    m = max(2, min(8, math.ceil(decades) + 1))
    hz = lo * pm.exp(np.arange(m) / (m - 1) * float(pm.log(hi / lo)))  # geometric, lo to hi
    hz[0], hz[-1] = lo, hi
    v = noise.flicker_noise_v / volts_per_ln
    var = np.full(m, v * v / m)
    return hz, var


def temporal(noise: Any, volts_per_ln: float, plan: KernelNoise) -> None:
    hz, var = flicker_noise_poles(noise, volts_per_ln)
    plan.output_hz.extend(float(h) for h in hz)
    plan.output_var.extend(float(v) for v in var)
