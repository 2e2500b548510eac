"""Noise of the logarithmic pixel: analytic variances and fixed patterns.

Temporal noise is generated inside the photoreceptor kernel
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
from gevsim.pixel.params import REFERENCE_TEMPERATURE_K, NoiseParams, thermal_factor


def shot_noise_variance_ln(photocurrent_a: ArrayLike, cutoff_hz: ArrayLike) -> np.ndarray:
    """Stationary variance (ln units^2) of shot noise through a first-order low-pass.

    The shot noise of a current I has one-sided PSD 2 q I; in the log domain
    the relative fluctuation dI/I has PSD 2 q / I. A first-order low-pass with
    cutoff f_c has noise bandwidth (pi/2) f_c, so var = pi q f_c / I.
    """
    i = np.asarray(photocurrent_a, float)
    return math.pi * elementary_charge * np.asarray(cutoff_hz, float) / i


def flicker_noise_poles(noise: NoiseParams, volts_per_ln: float) -> tuple[np.ndarray, np.ndarray]:
    """Corner frequencies and variances of Ornstein-Uhlenbeck processes whose sum has
    a 1/f spectrum between the two corners (one pole per decade, equal variance:
    McWhorter's construction); total variance = (flicker_noise_v / n U_T)^2."""
    if noise.flicker_noise_v == 0:
        return np.zeros(0), np.zeros(0)
    lo, hi = noise.flicker_noise_low_hz, noise.flicker_noise_high_hz
    decades = float(pm.log10(hi / lo))
    m = max(2, min(8, math.ceil(decades) + 1))
    hz = lo * pm.exp(np.arange(m) / (m - 1) * float(pm.log(hi / lo)))  # geometric, lo to hi
    hz[0], hz[-1] = lo, hi
    v = noise.flicker_noise_v / volts_per_ln
    var = np.full(m, v * v / m)
    return hz, var


def output_noise_poles(noise: NoiseParams, volts_per_ln: float) -> tuple[np.ndarray, np.ndarray]:
    """All Ornstein-Uhlenbeck processes added to the output: the read noise (one pole at
    ``read_noise_bandwidth_hz``, so its statistics do not depend on the time step) and
    the 1/f poles."""
    hz, var = flicker_noise_poles(noise, volts_per_ln)
    if noise.read_noise_v > 0:
        hz = np.r_[noise.read_noise_bandwidth_hz, hz]
        var = np.r_[(noise.read_noise_v / volts_per_ln) * (noise.read_noise_v / volts_per_ln), var]
    return hz, var


def dark_current_a(noise: NoiseParams, temperature_k: float = REFERENCE_TEMPERATURE_K) -> float:
    """Mean dark current (A) at ``temperature_k``: ``dark_current_a`` (stated at
    :data:`~gevsim.pixel.params.REFERENCE_TEMPERATURE_K`) doubling every ``dark_current_doubling_k``."""
    return noise.dark_current_a * thermal_factor(temperature_k, noise.dark_current_doubling_k)


def shot_noise_factor(noise: NoiseParams) -> float:
    """How many equal shot-noise sources the photocurrent drives: the photodiode, and with
    ``feedback_shot_noise`` the photoreceptor's feedback transistor (same current, variance x2)."""
    return 2.0 if noise.feedback_shot_noise else 1.0


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
    fast = []
    if noise.shot_noise or noise.amplifier_noise_ln2_hz > 0:
        dark = dark_current_a(noise, photoreceptor.temperature_k)
        fast.append(float(photoreceptor.cutoff_at(max_photocurrent_a + dark)))
    if noise.read_noise_v > 0:
        fast.append(noise.read_noise_bandwidth_hz)
    if not fast:
        return None
    return STEP_FRACTION / (2.0 * math.pi * math.sqrt(max(fast) * f_out))
