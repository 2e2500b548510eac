"""Noise of the logarithmic pixel: analytic variances, fixed patterns and the step it needs.

The mechanisms themselves are entries of :data:`gevsim.pixel.mechanisms.NOISE_MECHANISMS`, one
module each. Temporal noise is generated inside the photoreceptor kernel
(:mod:`gevsim.pixel._kernels`); this module holds the analytic results it must
reproduce and draws the per-pixel fixed patterns from a numpy Generator.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike
from scipy.constants import elementary_charge

from gevsim import _portable as pm
from gevsim.pixel.mechanisms import kernel_noise
from gevsim.pixel.mechanisms.dark_current import dark_current_a
from gevsim.pixel.mechanisms.flicker import flicker_noise_poles
from gevsim.pixel.params import NoiseParams
from gevsim.pixel.thermal import REFERENCE_TEMPERATURE_K

__all__ = ["STEP_FRACTION", "NoiseLaw", "coarsest_step_s", "dark_current_a", "fixed_pattern", "flicker_noise_poles",
           "shot_noise_variance_ln"]


def shot_noise_variance_ln(photocurrent_a: ArrayLike, cutoff_hz: ArrayLike) -> np.ndarray:
    """Stationary variance (ln units^2) of shot noise through a first-order low-pass.

    The shot noise of a current I has one-sided PSD 2 q I; in the log domain
    the relative fluctuation dI/I has PSD 2 q / I. A first-order low-pass with
    cutoff f_c has noise bandwidth (pi/2) f_c, so var = pi q f_c / I.
    """
    i = np.asarray(photocurrent_a, float)
    return math.pi * elementary_charge * np.asarray(cutoff_hz, float) / i


def fixed_pattern(shape: Sequence[int], noise: NoiseParams, *, rng: np.random.Generator,
                  temperature_k: float = REFERENCE_TEMPERATURE_K) -> tuple[np.ndarray, np.ndarray]:
    """Per-pixel photocurrent gain (PRNU) and dark current (DSNU, lognormal), drawn once.

    The lognormal is scaled so that the mean dark current is :func:`dark_current_a` at ``temperature_k``.
    """
    gain = 1.0 + noise.prnu * rng.standard_normal(shape)
    gain = np.clip(gain, 0.0, None)
    s = noise.dark_current_spread
    dark = dark_current_a(noise, temperature_k) * pm.exp(s * rng.standard_normal(shape) - 0.5 * s * s)
    return gain, dark


#: The coarsest step, as a fraction of the fastest noise path's crossing time 1 / (2 pi sqrt(f_a f_out)),
#: at which noise-event rates stay within about 10 % of their limit (measured: benchmarks/step_convergence.py;
#: counts converge to first order in the step, from below). 0.5 sufficed for the issue-22 presets; with issue 23's
#: photoreceptor offsets (gradient comparators sitting near their thresholds) and 10 kHz photoreceptors, davis346 at
#: 1000 chip lux gave gradient rates 1338 / 1464 / 1526 ev/px/s at 0.5, 0.25 and 0.125 (14 % spread): 0.35 keeps the
#: spread within 10 % (tests/pixel/test_step_independence.py).
STEP_FRACTION = 0.35


def coarsest_step_s(photoreceptor: Any, noise: NoiseParams, max_photocurrent_a: float) -> float | None:
    """The longest time step at which noise-event rates do not depend on the step (within ~10 %),
    or None when there is no bound (no output pole, so no limit to converge to; or no noise).

    Each noise passes its own pole (the photoreceptor's cutoff at the brightest pixel for shot noise,
    ``read_noise_bandwidth_hz`` for read noise) and the output pole; a path of poles f_a and f_out
    crosses a level on a time scale 1 / (2 pi sqrt(f_a f_out)), which the step must resolve.
    """
    f_out = photoreceptor.second_pole_hz
    if f_out is None:
        return None
    plan = kernel_noise(noise, photoreceptor.volts_per_ln)
    fast = []
    if plan.on_photoreceptor_pole:
        dark = dark_current_a(noise, photoreceptor.temperature_k)
        fast.append(float(photoreceptor.cutoff_at(max_photocurrent_a + dark)))
    fast += plan.cascaded_hz
    if not fast:
        return None
    return STEP_FRACTION / (2.0 * math.pi * math.sqrt(max(fast) * f_out))


@dataclass(frozen=True)
class NoiseLaw:
    """The photoreceptor output's temporal noise as white noises each through its own pole and the output pole,
    at any total photocurrent I (A), as the photoreceptor kernel draws it (:mod:`gevsim.pixel._cascade`):

    - shot and amplifier noise after the photoreceptor's pole f_c = min(fc_per_a I, fc_max_hz) (moved off the
      output pole as the kernel moves it): variance (shot_q f_c / I + amp_ln2_hz / f_c) beta / (alpha + beta)
      at the output, alpha = 2 pi f_c, beta = 2 pi output_pole_hz;
    - the read noise after its own pole: variance ``read_var_ln2`` at the output, rate ``read_rate_rad_s``.

    The 1/f poles (one pole each, no output pole) are not part of it."""

    shot_q: float
    amp_ln2_hz: float
    fc_per_a: float
    fc_max_hz: float
    output_pole_hz: float
    read_var_ln2: float
    read_rate_rad_s: float

    def as_tuple(self) -> tuple[float, ...]:
        """The fields in order, as floats (a compiled kernel's argument)."""
        return tuple(float(getattr(self, f)) for f in self.__dataclass_fields__)

    def components(self, total_a: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """(var, rate), each (2, pixels): each component's variance at the output (ln^2) and own pole (rad/s)
        at total photocurrent ``total_a``; a component the sensor does not have has variance 0."""
        from gevsim.pixel._cascade import separated_hz

        itot = np.asarray(total_a, float).reshape(-1)
        beta = 2.0 * math.pi * self.output_pole_hz
        fc = separated_hz(np.minimum(self.fc_per_a * itot, self.fc_max_hz), self.output_pole_hz)
        alpha = 2.0 * math.pi * fc
        var_s = (self.shot_q * fc / itot + self.amp_ln2_hz / fc) * beta / (alpha + beta)
        var = np.stack([var_s, np.full(itot.shape, self.read_var_ln2)])
        rate = np.stack([alpha, np.full(itot.shape, self.read_rate_rad_s)])
        return var, rate
