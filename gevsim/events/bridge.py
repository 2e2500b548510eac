"""Level crossings between two samples of a comparator's input, given both (issue 37, item 1: long steps).

A comparator that sees its input only at the ends of a step misses the crossings in between: that is why
:func:`gevsim.pixel.noise.coarsest_step_s` keeps the driver's steps at ~20 us for davis346. Given both samples,
the input inside the step is a Gaussian bridge: its noise is a sum of white noises each through two poles
(:meth:`gevsim.pixel.Photoreceptor.noise_components`), a stationary differentiable Gaussian process, and the
expected number of crossings of a level between the samples follows from Rice's formula on that bridge
(:mod:`gevsim.events._bridge`). :func:`crossings` returns, per pixel, the probability of an ON crossing and of
an OFF crossing within the step and, for given uniforms, when.

Measured against the driver's converged 20-us steps (``benchmarks/bridge_crossings.py``, davis346, 64x64 px,
1 s): noise-event rates within -5 % to +9 % from 0.1 to 1000 chip lux at steps of 250 us to 2 ms on a static
scene, and within -1 % to +3 % under a 5 Hz, +-0.3 ln sinusoid (docs/long-steps.md, "Rice bridge"). The
Ornstein-Uhlenbeck bridge of the photoreceptor pole alone breaks where that pole's rate times the step exceeds
~1 (from 10 chip lux at 500 us): the output pole and the read noise make the path smooth, and only the full
covariance describes it there.

The DVS and the gradient comparators use it when given a :class:`Bridge`
(:meth:`gevsim.events.BrightnessEmulator.process`, :meth:`gevsim.events.GradientEmulator.process`:
:mod:`gevsim.events._bridge_gradient`), and so does the driver with ``crossings = "bridge"``
(:mod:`gevsim.emulation.bridging`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from gevsim.events import _bridge
from gevsim.pixel.noise import NoiseLaw

#: Sides further than this many noise standard deviations (beyond the samples' own excursion) from their level
#: are not integrated: their probability is below ~1e-11 per step.
FAR_SD = _bridge.Z_SKIP


def crossings(x0: ArrayLike, x1: ArrayLike, gap_on: tuple[ArrayLike, ArrayLike], gap_off: tuple[ArrayLike, ArrayLike],
              step_s: float, var: ArrayLike, rate: ArrayLike, output_pole_rad_s: float,
              uniforms: tuple[ArrayLike, ArrayLike] | None = None) -> tuple[np.ndarray, ...]:
    """Per pixel, the probability that the input crossed its ON level upward and its OFF level downward
    between two samples ``step_s`` apart, and the crossing times as fractions of the step.

    Parameters
    ----------
    x0, x1 : (P,) the noise at the two samples (the input minus its noise-free value), ln.
    gap_on : (gap at the first sample, gap at the second), each (P,): how far the ON level is above the input
        (ln); the level is a straight line in time between them (the leak and the noise-free signal's change).
        A side with a gap <= 0 at either end is not a crossing between the samples (the comparator sees it at
        the sample) and gets probability 0.
    gap_off : likewise, how far the input is above the OFF level.
    var, rate : (K, P) the noise components (:meth:`gevsim.pixel.Photoreceptor.noise_components`): variance at
        the input (ln^2) and own pole (rad/s) of each white noise, all through the output pole.
    output_pole_rad_s : the common output pole's rate.
    uniforms : (u_on, u_off), each (P,) in [0, 1): place the crossing times (default: the middle of the step's
        crossing intensity, u = 0.5).

    Returns
    -------
    p_on, p_off, when_on, when_off : (P,) float64; probabilities in [0, 1), times in [0, 1] (1: no crossing).
    """
    x0 = np.ascontiguousarray(x0, dtype=np.float64).reshape(-1)
    x1 = np.ascontiguousarray(x1, dtype=np.float64).reshape(-1)
    n = x0.size
    var = np.ascontiguousarray(var, dtype=np.float64).reshape(-1, n)
    rate = np.ascontiguousarray(rate, dtype=np.float64).reshape(-1, n)
    if x1.size != n or var.shape != rate.shape:
        raise ValueError(f"crossings: x0 ({n}), x1 ({x1.size}), var {var.shape} and rate {rate.shape} differ in size")
    if not (math.isfinite(step_s) and step_s > 0.0):
        raise ValueError(f"crossings: step_s must be > 0, got {step_s!r}")
    b = float(output_pole_rad_s)
    if not (math.isfinite(b) and b > 0.0) or np.any(var < 0.0) or np.any(rate <= 0.0) or np.any(rate == b):
        raise ValueError("crossings: variances must be >= 0, pole rates > 0 and off the output pole "
                         f"({b!r} rad/s)")
    gaps = [np.ascontiguousarray(np.broadcast_to(np.asarray(g, np.float64).reshape(-1), (n,)))
            for g in (*gap_on, *gap_off)]
    u_on, u_off = (np.full(n, 0.5), np.full(n, 0.5)) if uniforms is None else (
        np.ascontiguousarray(np.broadcast_to(np.asarray(u, np.float64).reshape(-1), (n,))) for u in uniforms)
    out = [np.empty(n) for _ in range(4)]
    _bridge.crossings(x0, x1, *gaps, float(step_s), var, rate, b, *out, u_on, u_off, FAR_SD)
    return tuple(out)


@dataclass(frozen=True)
class Bridge:
    """What a DVS needs to place crossings between its samples (:meth:`BrightnessEmulator.process
    <gevsim.events.BrightnessEmulator.process>`'s ``bridge``): at the same T samples as its signal,

    noise_free : (T, H, W) the signal without its temporal noise (a noise-free twin of the photoreceptor);
    total_a : (T, H, W) the total photocurrent over each step ending at a sample (A), which sets the noise law;
    law : the photoreceptor's :class:`~gevsim.pixel.noise.NoiseLaw` (:meth:`Photoreceptor.noise_law
        <gevsim.pixel.Photoreceptor.noise_law>`).
    """

    noise_free: ArrayLike
    total_a: ArrayLike
    law: NoiseLaw

    def arrays(self, shape: tuple[int, ...], first: bool) -> tuple[np.ndarray, np.ndarray]:
        """(noise_free, total_a) as (T, pixels) arrays checked against the signal's ``shape`` (T, H, W); the
        photocurrent without its first sample when that sample only sets the levels (``first``)."""
        mu = np.asarray(self.noise_free, dtype=np.float32)
        itot = np.asarray(self.total_a, dtype=np.float32)
        for name, a in (("noise_free", mu), ("total_a", itot)):
            if a.shape != tuple(shape):
                raise ValueError(f"bridge.{name} has shape {a.shape}, the signal {tuple(shape)}")
        if not (np.all(np.isfinite(mu)) and np.all(itot > 0.0)):
            raise ValueError("bridge: noise_free must be finite and total_a > 0")
        n = int(np.prod(shape[1:]))
        mu, itot = mu.reshape(-1, n), itot.reshape(-1, n)
        return np.ascontiguousarray(mu), np.ascontiguousarray(itot[1:] if first else itot)
