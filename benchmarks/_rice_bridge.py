"""Prototype crossing rule for long steps (issue 37, item 1): the expected number of level crossings of the
photoreceptor output between two samples, given both, by Rice's formula on the Gaussian bridge of its noise.

The output's noise x (ln) is stationary Gaussian with covariance C(tau) = sum_i v_i rho_i(tau), each white noise
through its own pole (rate a_i) and the output pole (rate b): rho_i = (b e^(-a_i tau) - a_i e^(-b tau)) / (b - a_i)
(``Photoreceptor.output_noise_law``). x is differentiable (Var x' = sum_i v_i a_i b). Given x(0) = x0 and
x(h) = x1, x(t) and x'(t) are jointly Gaussian with moments in closed form; the expected number of up-crossings
of a barrier B(t) (linear in t) over (0, h) is (Rice 1944, for a non-stationary Gaussian path)

    E N = int_0^h phi_v(B - m) E[(x' - B')^+ | x = B] dt,

by Gauss-Legendre quadrature. P(crossing) = 1 - exp(-E N).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

_SQ2PI = math.sqrt(2.0 * math.pi)


@njit(inline="always")
def _cov(tau, v_s, a_s, v_r, a_r, b):
    """C(tau) and C'(tau) of the two components."""
    es, er, eb = math.exp(-a_s * tau), math.exp(-a_r * tau), math.exp(-b * tau)
    c = v_s * (b * es - a_s * eb) / (b - a_s) + v_r * (b * er - a_r * eb) / (b - a_r)
    d = v_s * a_s * b * (eb - es) / (b - a_s) + v_r * a_r * b * (eb - er) / (b - a_r)
    return c, d


@njit(inline="always")
def _ncdf(z):
    return 0.5 * math.erfc(-z / math.sqrt(2.0))


@njit(inline="always")
def _expected(x0, x1, g0, g1, h, v_s, a_s, v_r, a_r, b, nodes, weights):
    """Expected up-crossings over (0, h) of the barrier B(t) = x0 + g0 + (x1 + g1 - x0 - g0) t / h by x, given
    x(0) = x0, x(h) = x1 (g0, g1 > 0: the gaps at the ends)."""
    s2, _ = _cov(0.0, v_s, a_s, v_r, a_r, b)
    r, _ = _cov(h, v_s, a_s, v_r, a_r, b)
    lam = v_s * a_s * b + v_r * a_r * b
    det = s2 * s2 - r * r
    b0, b1 = x0 + g0, x1 + g1
    slope = (b1 - b0) / h
    total = 0.0
    for q in range(nodes.size):
        t = nodes[q] * h
        k1, k1p = _cov(t, v_s, a_s, v_r, a_r, b)
        k2, k2m = _cov(h - t, v_s, a_s, v_r, a_r, b)
        k2p = -k2m
        a1 = (s2 * k1 - r * k2) / det
        a2 = (s2 * k2 - r * k1) / det
        m = a1 * x0 + a2 * x1
        v = s2 - (a1 * k1 + a2 * k2)
        if v <= 1e-30:
            continue
        d1 = (s2 * k1p - r * k2p) / det
        d2 = (s2 * k2p - r * k1p) / det
        mp = d1 * x0 + d2 * x1
        wv = lam - (d1 * k1p + d2 * k2p)
        cq = -(a1 * k1p + a2 * k2p)  # Cov(x, x' | ends)
        bt = b0 + slope * t
        z = (bt - m) / math.sqrt(v)
        if z > 12.0:
            continue
        dens = math.exp(-0.5 * z * z) / (_SQ2PI * math.sqrt(v))
        mu = mp + cq / v * (bt - m) - slope
        sd = math.sqrt(max(wv - cq * cq / v, 1e-300))
        u = mu / sd
        total += weights[q] * h * dens * (mu * _ncdf(u) + sd * math.exp(-0.5 * u * u) / _SQ2PI)
    return total


@njit(parallel=True, cache=True)
def crossing_probability(x0, x1, gap_on0, gap_on1, gap_off0, gap_off1, h, v_s, a_s, v_r, a_r, b, nodes, weights,
                         p_on, p_off):
    """Per pixel: the probability of an ON (up, to gap_on above) and an OFF (down) crossing over (0, h)."""
    for p in prange(x0.size):
        sd = math.sqrt(v_s[p] + v_r)
        if min(gap_on0[p], gap_on1[p]) > 0.0:
            far = min(gap_on0[p] + x0[p], gap_on1[p] + x1[p]) - max(max(x0[p], x1[p]), 0.0) > 9.0 * sd
            e = 0.0 if far else _expected(x0[p], x1[p], gap_on0[p], gap_on1[p], h, v_s[p], a_s[p], v_r, a_r, b,
                                          nodes, weights)
            p_on[p] = 1.0 - math.exp(-e)
        else:
            p_on[p] = 0.0
        if min(gap_off0[p], gap_off1[p]) > 0.0:
            far = min(gap_off0[p] - x0[p], gap_off1[p] - x1[p]) - max(max(-x0[p], -x1[p]), 0.0) > 9.0 * sd
            e = 0.0 if far else _expected(-x0[p], -x1[p], gap_off0[p], gap_off1[p], h, v_s[p], a_s[p], v_r, a_r,
                                          b, nodes, weights)
            p_off[p] = 1.0 - math.exp(-e)
        else:
            p_off[p] = 0.0


def gauss_legendre(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Nodes on (0, 1) and weights summing to 1."""
    x, w = np.polynomial.legendre.leggauss(n)
    return 0.5 * (x + 1.0), 0.5 * w
