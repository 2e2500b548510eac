"""The stationary law of a DVS pixel's memorised level given its noise (issue 34, item 1).

Let u = ref - s be a pixel's memorised level relative to its noise-free signal s. Between events
the leak lowers u at D ln/s; the noise n (Gaussian, standard deviation sigma, Rice frequency nu)
fires an ON event when n > theta_on + u and an OFF event when n < u - theta_off, at the rates
r(w) = nu exp(-w^2 / 2 sigma^2) of crossing the distance w to each threshold (Rice 1944, "Mathematical
analysis of random noise", eq. 3.3-11); after either event the change amplifier is reset and u
starts afresh at the noise's value on release plus the reset error. The noise is still correlated
with the level it crossed (rho, its correlation over the refractory period): after an ON event from u
the new level is N(rho (theta_on + u), sigma^2 (1 - rho^2) + sigma_reset^2), after an OFF event
N(rho (u - theta_off), ...), so a pixel that fired ON starts nearer its OFF threshold. The reinjection
law g is taken as one normal per polarity, with the flux-weighted mean and variance of where the
pixels fire, and solved to its fixed point with the density (ITERATIONS passes, starting from rho = 0). The
stationary density solves D p'(u) - R(u) p(u) + J g(u) = 0, R = r_on + r_off: from the top down,
over a cell of width h where R is constant,

    p(u - h) = p(u) e^(-R h / D) + g (1 - e^(-R h / D)) / R,

which is the leak phase's uniform law below the reset point where the noise cannot reach,
empties near a threshold where the noise would already have fired, and tends to the dwell-time law
g / R when the leak is negligible (a noisy pixel spends its time where it fires least).
The law assumes the noise at t = 0 independent of the level; the driver's burn-in settles the rest.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from gevsim._portable import exp_scalar

#: Cells of the level grid between the two thresholds.
CELLS = 128
#: Passes of the fixed point between the density and where its events reinject (4 settle it to < 1 %).
ITERATIONS = 4


@njit(inline="always")
def _gauss(z):
    return exp_scalar(-0.5 * z * z)


@njit(cache=True)
def _cells(lo, h, theta_on, theta_off, s, nu, drift, r_on, r_off, decay, weight):
    """Per cell, what does not change between passes: the ON and OFF crossing rates, the survival over
    the cell at the leak's drift (decay) and the weight of a reinjection there (gain = g x weight)."""
    for k in range(CELLS):
        u = lo + (k + 0.5) * h
        r_on[k] = nu * _gauss((theta_on + u) / s)
        r_off[k] = nu * _gauss((theta_off - u) / s)
        rate = r_on[k] + r_off[k]
        if drift > 0.0:
            x = rate * h / drift
            decay[k] = exp_scalar(-x)
            weight[k] = h / drift if x < 1e-12 else (1.0 - decay[k]) / rate
        else:
            decay[k], weight[k] = 0.0, 1.0 / max(rate, 1e-300)


@njit(cache=True)
def _density(lo, h, decay, weight, mix, p):
    """p (CELLS,) for the reinjection mixture ``mix`` = (weight, mean, sd) x 2; returns its total."""
    carry = 0.0
    total = 0.0
    for k in range(CELLS - 1, -1, -1):
        u = lo + (k + 0.5) * h
        g = 0.0
        for j in range(2):
            if mix[j, 0] > 0.0:
                g += mix[j, 0] / mix[j, 2] * _gauss((u - mix[j, 1]) / mix[j, 2])
        carry = carry * decay[k] + g * weight[k]
        p[k] = carry
        total += carry
    return total


@njit(cache=True, parallel=True)
def draw_levels(theta_on: np.ndarray, theta_off: np.ndarray, sigma: np.ndarray, nu: np.ndarray, rho: np.ndarray,
                drift: np.ndarray, reset_sigma: float, uniform: np.ndarray, out: np.ndarray) -> None:
    """Draw u (out) per pixel by the inverse of its stationary CDF at ``uniform`` (all arrays (P,); ``rho``:
    the noise's correlation over the refractory period)."""
    for i in prange(out.shape[0]):
        lo, hi = -theta_on[i], theta_off[i]
        h = (hi - lo) / CELLS
        s = max(sigma[i], 1e-12)
        if nu[i] <= 0.0 and drift[i] <= 0.0:  # neither noise nor leak: the level stays at the reset point
            out[i] = 0.0
            continue
        r = min(max(rho[i], 0.0), 1.0)
        spread = math.sqrt(s * s * (1.0 - r * r) + reset_sigma * reset_sigma) + 1e-12
        mix = np.zeros((2, 3))
        mix[0, 0], mix[0, 2] = 1.0, math.sqrt(s * s + reset_sigma * reset_sigma) + 1e-12
        mix[1, 2] = spread
        p = np.empty(CELLS)
        r_on, r_off, decay, weight = np.empty(CELLS), np.empty(CELLS), np.empty(CELLS), np.empty(CELLS)
        _cells(lo, h, theta_on[i], theta_off[i], s, nu[i], drift[i], r_on, r_off, decay, weight)
        total = 0.0
        for _ in range(ITERATIONS):
            total = _density(lo, h, decay, weight, mix, p)
            # Where the pixels fire from: each polarity's flux and the mean and variance of the noise level
            # it crossed (n = theta_on + u for ON, u - theta_off for OFF); their release is at rho times it.
            flux = np.zeros(2)
            m1 = np.zeros(2)
            m2 = np.zeros(2)
            for k in range(CELLS):
                u = lo + (k + 0.5) * h
                for j in range(2):
                    n = theta_on[i] + u if j == 0 else u - theta_off[i]
                    f = (r_on[k] if j == 0 else r_off[k]) * p[k]
                    flux[j] += f
                    m1[j] += f * n
                    m2[j] += f * n * n
            if flux[0] + flux[1] <= 0.0 or nu[i] <= 0.0:
                break
            for j in range(2):
                mean = m1[j] / flux[j] if flux[j] > 0 else 0.0
                var = max(m2[j] / flux[j] - mean * mean, 0.0) if flux[j] > 0 else 0.0
                mix[j, 0] = flux[j] / (flux[0] + flux[1])
                mix[j, 1] = r * mean
                mix[j, 2] = math.sqrt(spread * spread + r * r * var)
        target = uniform[i] * total
        acc = 0.0
        k = 0
        while k < CELLS - 1 and acc + p[k] < target:
            acc += p[k]
            k += 1
        frac = (target - acc) / p[k] if p[k] > 0.0 else 0.5
        out[i] = lo + (k + min(max(frac, 0.0), 1.0)) * h
