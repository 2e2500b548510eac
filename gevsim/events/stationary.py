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


@njit(cache=True)
def _gauss_row(z0, dz, scale, out):
    """out[k] += scale exp(-(z0 + k dz)^2 / 2) for every cell k, with three exponentials in all: from the
    cell nearest the peak outwards, each value is the last times a ratio, and each ratio the last times
    exp(-dz^2) (the ratio of a Gaussian's neighbouring samples on an even grid is itself geometric). Every
    factor is at most 1, so nothing overflows, and a value that underflows is below 1e-308 of the peak. The
    products agree with an exponential per cell to 1e-11 relative (tests/events/test_stationary_grid.py), at
    ~150 exponentials per pixel instead of ~1,400 (the start's largest cost at 1280x720 before)."""
    c = 0
    if dz > 0.0:
        c = int(min(max(round(-z0 / dz), 0.0), CELLS - 1.0))
    zc = z0 + c * dz
    peak = exp_scalar(-0.5 * zc * zc)
    q = exp_scalar(-dz * dz)
    out[c] += scale * peak
    g = peak
    r = exp_scalar(-zc * dz - 0.5 * dz * dz)
    for k in range(c + 1, CELLS):
        g *= r
        r *= q
        out[k] += scale * g
    g = peak
    r = exp_scalar(zc * dz - 0.5 * dz * dz)
    for k in range(c - 1, -1, -1):
        g *= r
        r *= q
        out[k] += scale * g


@njit(cache=True)
def _cells(lo, h, theta_on, theta_off, s, nu, drift, r_on, r_off, decay, weight):
    """Per cell, what does not change between passes: the ON and OFF crossing rates, the survival over
    the cell at the leak's drift (decay) and the weight of a reinjection there (gain = g x weight)."""
    r_on[:] = 0.0
    r_off[:] = 0.0
    _gauss_row((theta_on + lo + 0.5 * h) / s, h / s, nu, r_on)  # distance to the ON threshold, rising with u
    _gauss_row((lo + 0.5 * h - theta_off) / s, h / s, nu, r_off)  # minus the distance to OFF (same Gaussian)
    for k in range(CELLS):
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
    p[:] = 0.0  # first the reinjection law g per cell, then the density in place from the top down
    for j in range(2):
        if mix[j, 0] > 0.0:
            _gauss_row((lo + 0.5 * h - mix[j, 1]) / mix[j, 2], h / mix[j, 2], mix[j, 0] / mix[j, 2], p)
    carry = 0.0
    total = 0.0
    for k in range(CELLS - 1, -1, -1):
        carry = carry * decay[k] + p[k] * weight[k]
        p[k] = carry
        total += carry
    return total


#: Pixels per parallel work item of :func:`draw_levels` (its scratch arrays are made once per item).
_BLOCK = 256


@njit(cache=True)
def _level(theta_on, theta_off, s, nu, rho, drift, reset_sigma, uniform, p, r_on, r_off, decay, weight, mix):
    """One pixel's level u: its stationary density (p; the rest are scratch of CELLS, and mix (2, 3)) solved to
    its fixed point with where its events reinject, and inverted at ``uniform``."""
    lo, hi = -theta_on, theta_off
    h = (hi - lo) / CELLS
    s = max(s, 1e-12)
    if nu <= 0.0 and drift <= 0.0:  # neither noise nor leak: the level stays at the reset point
        return 0.0
    r = min(max(rho, 0.0), 1.0)
    spread = math.sqrt(s * s * (1.0 - r * r) + reset_sigma * reset_sigma) + 1e-12
    mix[:] = 0.0
    mix[0, 0], mix[0, 2] = 1.0, math.sqrt(s * s + reset_sigma * reset_sigma) + 1e-12
    mix[1, 2] = spread
    _cells(lo, h, theta_on, theta_off, s, nu, drift, r_on, r_off, decay, weight)
    total = 0.0
    for _ in range(ITERATIONS):
        total = _density(lo, h, decay, weight, mix, p)
        # Where the pixels fire from: each polarity's flux and the mean and variance of the noise level
        # it crossed (n = theta_on + u for ON, u - theta_off for OFF); their release is at rho times it.
        f_on = m1_on = m2_on = f_off = m1_off = m2_off = 0.0
        for k in range(CELLS):
            u = lo + (k + 0.5) * h
            n_on, n_off = theta_on + u, u - theta_off
            a, b = r_on[k] * p[k], r_off[k] * p[k]
            f_on += a
            m1_on += a * n_on
            m2_on += a * n_on * n_on
            f_off += b
            m1_off += b * n_off
            m2_off += b * n_off * n_off
        if f_on + f_off <= 0.0 or nu <= 0.0:
            break
        for j, f, m1, m2 in ((0, f_on, m1_on, m2_on), (1, f_off, m1_off, m2_off)):
            mean = m1 / f if f > 0 else 0.0
            var = max(m2 / f - mean * mean, 0.0) if f > 0 else 0.0
            mix[j, 0] = f / (f_on + f_off)
            mix[j, 1] = r * mean
            mix[j, 2] = math.sqrt(spread * spread + r * r * var)
    target = uniform * total
    acc = 0.0
    k = 0
    while k < CELLS - 1 and acc + p[k] < target:
        acc += p[k]
        k += 1
    frac = (target - acc) / p[k] if p[k] > 0.0 else 0.5
    return lo + (k + min(max(frac, 0.0), 1.0)) * h


@njit(cache=True, parallel=True)
def draw_levels(theta_on: np.ndarray, theta_off: np.ndarray, sigma: np.ndarray, nu: np.ndarray, rho: np.ndarray,
                drift: np.ndarray, reset_sigma: float, uniform: np.ndarray, out: np.ndarray) -> None:
    """Draw u (out) per pixel by the inverse of its stationary CDF at ``uniform`` (all arrays (P,); ``rho``:
    the noise's correlation over the refractory period)."""
    n = out.shape[0]
    for b in prange((n + _BLOCK - 1) // _BLOCK):
        p, r_on, r_off = np.empty(CELLS), np.empty(CELLS), np.empty(CELLS)
        decay, weight, mix = np.empty(CELLS), np.empty(CELLS), np.empty((2, 3))
        for i in range(b * _BLOCK, min(n, (b + 1) * _BLOCK)):
            out[i] = _level(theta_on[i], theta_off[i], sigma[i], nu[i], rho[i], drift[i], reset_sigma, uniform[i],
                            p, r_on, r_off, decay, weight, mix)
