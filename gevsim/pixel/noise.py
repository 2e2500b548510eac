"""Noise of the logarithmic pixel: analytic variances, fixed patterns and the step it needs.

The mechanisms themselves are entries of :data:`gevsim.pixel.mechanisms.NOISE_MECHANISMS`, one
module each. Temporal noise is generated inside the photoreceptor kernel
(:mod:`gevsim.pixel._kernels`); this module holds the analytic results it must
reproduce and draws the per-pixel fixed patterns from a numpy Generator.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
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

__all__ = ["STEP_FRACTION", "coarsest_step_s", "dark_current_a", "fixed_pattern", "flicker_noise_poles",
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
