"""Compiled kernel of :mod:`gevsim.events.bridge`: the probability that a comparator's input crossed a level
between two samples, given both, and when (Rice's formula on the Gaussian bridge of its noise).

The noise x is a sum of K components, each a white noise through its own pole (rate a_k) and a common output
pole (rate b): covariance C(tau) = sum_k v_k (b e^(-a_k tau) - a_k e^(-b tau)) / (b - a_k) and
C'(tau) = sum_k v_k a_k b (e^(-b tau) - e^(-a_k tau)) / (b - a_k), -C''(0) = sum_k v_k a_k b (the derivative's
variance: x is differentiable). Given x(0) = x0 and x(h) = x1, x(t) and x'(t) are jointly Gaussian, with

    m(t) = A1 x0 + A2 x1,  [A1 A2] = [C(t) C(h - t)] M^-1,  M = [[C(0), C(h)], [C(h), C(0)]],
    v(t) = C(0) - A1 C(t) - A2 C(h - t),
    m'(t) = D1 x0 + D2 x1,  [D1 D2] = [C'(t) -C'(h - t)] M^-1,  w(t) = -C''(0) - D1 C'(t) + D2 C'(h - t),
    c(t) = Cov(x, x') = -A1 C'(t) + A2 C'(h - t).

The expected number of up-crossings of a barrier B(t) = B0 + (B1 - B0) t / h over (0, h) (Rice 1944; Cramer &
Leadbetter 1967, ch. 13, for a non-stationary Gaussian path) is

    E = int_0^h phi(z) / sqrt(v) [mu Phi(mu / s) + s phi(mu / s)] dt,   z = (B - m) / sqrt(v),
    mu = m' + c (B - m) / v - B',   s^2 = w - c^2 / v,

computed by Gauss-Legendre quadrature on NODES points, and P(a crossing) = 1 - exp(-E). Every exponential is
the single-precision polynomial of :mod:`gevsim.pixel._fastmath` and Phi a polynomial (Abramowitz & Stegun
7.1.26), so the result is the same on every CPU.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from gevsim.pixel._fastmath import expf

_F = np.float32
_INV_SQ2PI = 1.0 / math.sqrt(2.0 * math.pi)

#: Pixels per parallel task (each allocates its scratch once).
BLOCK = 256
#: Quadrature points per step (Gauss-Legendre, symmetric: the node h - t of node t is a node too).
NODES = 16
#: Nodes at which the level is further than this many conditional standard deviations add nothing
#: (phi(Z_SKIP) = 1.2e-11 against the rates' ~1e-3 statistical error).
Z_SKIP = 7.0


def _nodes(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Gauss-Legendre in s on (0, 1), mapped by t = s^2 (3 - 2 s): nodes crowd toward both ends, where the
    crossings crowd when a sample lies near its level (the map keeps the node set symmetric about 1/2).
    Returns the nodes, their weights (summing to 1) and the cells' bounds (node q's cell: CELL[q], CELL[q + 1],
    the image of its Gauss-Legendre cell)."""
    x, w = np.polynomial.legendre.leggauss(n)
    s, ws = 0.5 * (x + 1.0), 0.5 * w
    bounds = np.concatenate(([0.0], np.cumsum(ws)))
    bounds[-1] = 1.0
    return s * s * (3.0 - 2.0 * s), ws * 6.0 * s * (1.0 - s), bounds * bounds * (3.0 - 2.0 * bounds)


#: Nodes on (0, 1), their weights and cells (:func:`_nodes`); a crossing drawn at a node is placed in its cell.
XI, WEIGHT, CELL = _nodes(NODES)


@njit(inline="always")
def _exp(x):
    return np.float64(expf(_F(max(x, -87.0))))


@njit(inline="always")
def _upper_tail(u):
    """Phi(-u) for u >= 0 (A&S 7.1.26 on erfc(u / sqrt 2): absolute error < 1.5e-7 / 2)."""
    t = 1.0 / (1.0 + 0.3275911 * u * 0.7071067811865476)
    poly = t * (0.254829592 + t * (-0.284496736 + t * (1.421413741 + t * (-1.453152027 + t * 1.061405429))))
    return 0.5 * poly * _exp(-0.5 * u * u)


@njit(inline="always")
def _mean_excess(mu, s):
    """E[(Y)^+] for Y ~ N(mu, s^2), s > 0."""
    u = mu / s
    pdf = _exp(-0.5 * u * u) * _INV_SQ2PI
    cdf = 1.0 - _upper_tail(u) if u >= 0.0 else _upper_tail(-u)
    return mu * cdf + s * pdf


@njit(inline="always")
def _covariances(var, rate, p, b, h, eb, ea, last, c, cp):
    """C and C' of pixel p at 0, h and the nodes: c[0] = C(0), c[1 + q] = C(XI[q] h), c[NODES + 1] = C(h);
    cp likewise (cp[0] = -C''(0), the derivative's variance). eb: e^(-b tau) at the same points; ea[k]:
    e^(-a_k tau), recomputed only when component k's rate differs from ``last[k]`` (the pixel before's)."""
    n = c.shape[0]
    for j in range(n):
        c[j] = 0.0
        cp[j] = 0.0
    for k in range(var.shape[0]):
        v = var[k, p]
        a = rate[k, p]
        if v <= 0.0:
            continue
        if a != last[k]:
            for j in range(1, n):
                ea[k, j] = _exp(-a * (XI[j - 1] * h if j < n - 1 else h))
            last[k] = a
        g = 1.0 / (b - a)
        cp[0] += v * a * b
        c[0] += v
        for j in range(1, n):
            c[j] += v * (b * ea[k, j] - a * eb[j]) * g
            cp[j] += v * a * b * (eb[j] - ea[k, j]) * g


@njit(inline="always")
def _side(x0, x1, g0, g1, h, c, cp, share):
    """Expected up-crossings of B(t) = x0 + g0 + (x1 + g1 - x0 - g0) t / h over (0, h) given x(0) = x0 and
    x(h) = x1 (g0, g1 > 0), from the covariances of :func:`_covariances`; share[q] receives each node's part."""
    s2 = c[0]
    r = c[NODES + 1]
    lam = cp[0]
    det = s2 * s2 - r * r
    b0 = x0 + g0
    slope = (x1 + g1 - b0) / h
    total = 0.0
    for q in range(NODES):
        share[q] = 0.0
        k1, k1p = c[1 + q], cp[1 + q]
        k2, k2p = c[NODES - q], -cp[NODES - q]  # C(h - t) and d/dt C(h - t): the mirrored node
        a1 = (s2 * k1 - r * k2) / det
        a2 = (s2 * k2 - r * k1) / det
        m = a1 * x0 + a2 * x1
        v = s2 - (a1 * k1 + a2 * k2)
        if v <= 1e-12 * s2:
            continue
        gap = b0 + slope * XI[q] * h - m
        sd = math.sqrt(v)
        z = gap / sd
        if z > Z_SKIP:
            continue
        d1 = (s2 * k1p - r * k2p) / det
        d2 = (s2 * k2p - r * k1p) / det
        cq = -(a1 * k1p + a2 * k2p)
        mu = d1 * x0 + d2 * x1 + cq / v * gap - slope
        s = math.sqrt(max(lam - (d1 * k1p + d2 * k2p) - cq * cq / v, 1e-30 * lam))
        part = WEIGHT[q] * h * _exp(-0.5 * z * z) * _INV_SQ2PI / sd * _mean_excess(mu, s)
        share[q] = part
        total += part
    return total


@njit(inline="always")
def _when(share, total, u):
    """A crossing's time as a fraction of the step: the node whose share of ``total`` u (in [0, 1)) falls in,
    then the place in that node's cell where u falls within its share (uniform, given the node)."""
    target = u * total
    acc = 0.0
    for q in range(NODES):
        if share[q] <= 0.0:
            continue
        if acc + share[q] > target or q == NODES - 1:
            frac = min(max((target - acc) / share[q], 0.0), 1.0)
            return CELL[q] + frac * (CELL[q + 1] - CELL[q])
        acc += share[q]
    return 1.0


@njit(parallel=True, nogil=True, cache=True)
def crossings(x0, x1, gap_on0, gap_on1, gap_off0, gap_off1, h, var, rate, b, p_on, p_off, when_on, when_off, u_on,
              u_off, far_sd):
    """Per pixel: the probabilities p_on, p_off of an up-crossing of the ON level and a down-crossing of the OFF
    level over the step, and, for u_on, u_off in [0, 1), a time for each (fraction of the step). A side whose gap
    is not positive at an end, or that is further than ``far_sd`` noise standard deviations from the noise's
    reach, gets probability 0 without quadrature."""
    eb = np.empty(NODES + 2)
    eb[0] = 1.0
    for q in range(NODES):
        eb[1 + q] = _exp(-b * XI[q] * h)
    eb[NODES + 1] = _exp(-b * h)
    n_px = x0.size
    for blk in prange((n_px + BLOCK - 1) // BLOCK):
        c = np.empty(NODES + 2)
        cp = np.empty(NODES + 2)
        share = np.empty(NODES)
        ea = np.empty((var.shape[0], NODES + 2))
        last = np.full(var.shape[0], -1.0)
        for p in range(blk * BLOCK, min(n_px, (blk + 1) * BLOCK)):
            p_on[p] = 0.0
            p_off[p] = 0.0
            when_on[p] = 1.0
            when_off[p] = 1.0
            sd = 0.0
            for k in range(var.shape[0]):
                sd += var[k, p]
            reach = 1.5 * max(abs(x0[p]), abs(x1[p])) + far_sd * math.sqrt(sd)
            on_open = gap_on0[p] > 0.0 and gap_on1[p] > 0.0 and min(gap_on0[p] + x0[p], gap_on1[p] + x1[p]) < reach
            off_open = (gap_off0[p] > 0.0 and gap_off1[p] > 0.0
                        and min(gap_off0[p] - x0[p], gap_off1[p] - x1[p]) < reach)
            if not (on_open or off_open):
                continue
            _covariances(var, rate, p, b, h, eb, ea, last, c, cp)
            if on_open:
                e = _side(x0[p], x1[p], gap_on0[p], gap_on1[p], h, c, cp, share)
                if e > 0.0:
                    p_on[p] = 1.0 - _exp(-e)
                    when_on[p] = _when(share, e, u_on[p])
            if off_open:
                e = _side(-x0[p], -x1[p], gap_off0[p], gap_off1[p], h, c, cp, share)
                if e > 0.0:
                    p_off[p] = 1.0 - _exp(-e)
                    when_off[p] = _when(share, e, u_off[p])
