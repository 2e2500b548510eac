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
from numba import njit

from gevsim.pixel._cascade import separate
from gevsim.pixel._fastmath import expf

_F = np.float32
_INV_SQ2PI = 1.0 / math.sqrt(2.0 * math.pi)

#: Pixels per block of lanes (each block allocates its scratch once).
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
def _mean_excess(mu, s):
    """E[(Y)^+] for Y ~ N(mu, s^2), s > 0: s (u Phi(u) + phi(u)), u = mu / s, Phi by A&S 7.1.26 on
    erfc(|u| / sqrt 2) (absolute error < 1e-7), one exponential for both; branch-free."""
    u = mu / s
    a = abs(u)
    e = _exp(-0.5 * a * a)
    t = 1.0 / (1.0 + 0.3275911 * 0.7071067811865476 * a)
    tail = 0.5 * e * t * (0.254829592 + t * (-0.284496736 + t * (1.421413741 + t * (-1.453152027
                                                                                       + t * 1.061405429))))
    cdf = tail if u < 0.0 else 1.0 - tail
    return s * (u * cdf + e * _INV_SQ2PI)


@njit(inline="always")
def _covariances(lv, la, m, b, h, eb, c, cp):
    """C and C' of the m lanes (their components' variances lv[k, i] and rates la[k, i]) at 0, h and the nodes:
    c[0, i] = C(0), c[1 + q, i] = C(XI[q] h), c[NODES + 1, i] = C(h); cp likewise, but cp[0, i] = -C''(0) (the
    derivative's variance). eb: e^(-b tau) at the same points. Lane-wise loops (vectorised)."""
    n = c.shape[0]
    for j in range(n):
        for i in range(m):
            c[j, i] = 0.0
            cp[j, i] = 0.0
    for k in range(lv.shape[0]):
        for i in range(m):
            c[0, i] += lv[k, i]
            cp[0, i] += lv[k, i] * la[k, i] * b
        for j in range(1, n):
            tau = XI[j - 1] * h if j < n - 1 else h
            ebj = eb[j]
            for i in range(m):
                a = la[k, i]
                g = lv[k, i] / (b - a)
                ea = _exp(-a * tau)
                c[j, i] += g * (b * ea - a * ebj)
                cp[j, i] += g * a * b * (ebj - ea)


@njit(inline="always")
def _moments(c, cp, m, inv_det, mom):
    """The bridge's moments at each node for the m lanes, for any samples: mom[0..1, q, i] = A1, A2 (the mean),
    mom[2] = 1 / sqrt(v), mom[3..4] = D1, D2 (the derivative's mean), mom[5] = c / v, mom[6] = s (the
    derivative's conditional deviation). inv_det: scratch (m,)."""
    for i in range(m):
        inv_det[i] = 1.0 / (c[0, i] * c[0, i] - c[NODES + 1, i] * c[NODES + 1, i])
    for q in range(NODES):
        for i in range(m):
            s2 = c[0, i]
            r = c[NODES + 1, i]
            lam = cp[0, i]
            k1, k1p = c[1 + q, i], cp[1 + q, i]
            k2, k2p = c[NODES - q, i], -cp[NODES - q, i]  # C(h - t) and d/dt C(h - t): the mirrored node
            a1 = (s2 * k1 - r * k2) * inv_det[i]
            a2 = (s2 * k2 - r * k1) * inv_det[i]
            inv_v = 1.0 / max(s2 - (a1 * k1 + a2 * k2), 1e-12 * s2)
            d1 = (s2 * k1p - r * k2p) * inv_det[i]
            d2 = (s2 * k2p - r * k1p) * inv_det[i]
            cq = -(a1 * k1p + a2 * k2p)
            mom[0, q, i] = a1
            mom[1, q, i] = a2
            mom[2, q, i] = math.sqrt(inv_v)
            mom[3, q, i] = d1
            mom[4, q, i] = d2
            mom[5, q, i] = cq * inv_v
            mom[6, q, i] = math.sqrt(max(lam - (d1 * k1p + d2 * k2p) - cq * cq * inv_v, 1e-30 * lam))


@njit(inline="always")
def node_terms(x0, x1, g0, g1, tq, wq, h, mom, q, i):
    """At node q (time tq, weight wq h / sqrt(2 pi)) for lane i, bridge x0 -> x1 and barrier
    B(t) = x0 + g0 + (x1 + g1 - x0 - g0) t / h: the barrier's distance z in conditional deviations, the mean mu of
    x' - B' given x = B, and the node's density phi(z) / sqrt(v) times wq (:func:`_moments`' notation). A
    crossing's part is dens times E[(x' - B')^+] (up) or E[(B' - x')^+] (down)."""
    b0 = x0 + g0
    slope = (x1 + g1 - b0) / h
    gap = b0 + slope * tq - (mom[0, q, i] * x0 + mom[1, q, i] * x1)
    z = gap * mom[2, q, i]
    mu = mom[3, q, i] * x0 + mom[4, q, i] * x1 + mom[5, q, i] * gap - slope
    return z, mu, wq * _exp(-0.5 * z * z) * mom[2, q, i]


# Compiled on their own (not inlined) and cached: each kernel that calls them compiles in ~20 s less. Inlined
# into the DVS kernel they made it ~35 % faster in dim light (0.38 against 0.52 s for 1 s of 64x64 at 0.1 lux).
@njit(inline="never", cache=True, error_model="numpy", fastmath={"nnan", "ninf"})
def side(sx0, sx1, g0, g1, m, h, mom, share, total):
    """Expected up-crossings, per lane, of B(t) = x0 + g0 + (x1 + g1 - x0 - g0) t / h over (0, h) given
    x(0) = x0 and x(h) = x1 (lanes whose g0 or g1 is not positive get 0), from :func:`_moments`; share[q, i]
    receives each node's part, total[i] the sum. Nodes further than Z_SKIP deviations add 0."""
    for i in range(m):
        total[i] = 0.0
    for q in range(NODES):
        tq = XI[q] * h
        wq = WEIGHT[q] * h * _INV_SQ2PI
        for i in range(m):
            z, mu, dens = node_terms(sx0[i], sx1[i], g0[i], g1[i], tq, wq, h, mom, q, i)
            part = dens * _mean_excess(mu, mom[6, q, i])
            keep = (z <= Z_SKIP) & (g0[i] > 0.0) & (g1[i] > 0.0)
            part = part if keep else 0.0
            share[q, i] = part
            total[i] += part


@njit(inline="always")
def when(share, i, total, u):
    """A crossing's time as a fraction of the step: the node whose share of ``total`` u (in [0, 1)) falls in,
    then the place in that node's cell where u falls within its share (uniform, given the node)."""
    target = u * total
    acc = 0.0
    for q in range(NODES):
        part = share[q, i]
        if part <= 0.0:
            continue
        if acc + part > target or q == NODES - 1:
            frac = min(max((target - acc) / part, 0.0), 1.0)
            return CELL[q] + frac * (CELL[q + 1] - CELL[q])
        acc += part
    return 1.0


@njit(nogil=True, cache=True, error_model="numpy", fastmath={"nnan", "ninf"})
def crossings(x0, x1, gap_on0, gap_on1, gap_off0, gap_off1, h, var, rate, b, p_on, p_off, when_on, when_off, u_on,
              u_off, far_sd):
    """Per pixel: the probabilities p_on, p_off of an up-crossing of the ON level and a down-crossing of the OFF
    level over the step, and, for u_on, u_off in [0, 1), a time for each (fraction of the step). A side whose gap
    is not positive at an end, or whose level is further than ``far_sd`` noise standard deviations beyond the
    samples' excursion, gets probability 0 without quadrature. Pixels are taken in blocks of BLOCK; a block's
    open pixels are gathered into lanes, and every loop over lanes is branch-free (vectorised)."""
    eb = np.empty(NODES + 2)
    node_exps(b, h, eb)
    n_px = x0.size
    for blk in range((n_px + BLOCK - 1) // BLOCK):
        lo = blk * BLOCK
        hi = min(n_px, lo + BLOCK)
        idx = np.empty(BLOCK, np.int64)
        m = 0
        for p in range(lo, hi):
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
            if on_open or off_open:
                idx[m] = p
                m += 1
        if m == 0:
            continue
        c = np.empty((NODES + 2, m))
        cp = np.empty((NODES + 2, m))
        mom = np.empty((7, NODES, m))
        share = np.empty((NODES, m))
        total = np.empty(m)
        sx0 = np.empty(m)
        sx1 = np.empty(m)
        g0 = np.empty(m)
        g1 = np.empty(m)
        lv = np.empty((var.shape[0], m))
        la = np.empty((var.shape[0], m))
        for k in range(var.shape[0]):
            for i in range(m):
                lv[k, i] = var[k, idx[i]]
                la[k, i] = rate[k, idx[i]]
        lanes(lv, la, m, b, h, eb, c, cp, mom, total)
        for off_side in range(2):
            sign = 1.0 if off_side == 0 else -1.0
            for i in range(m):
                p = idx[i]
                sx0[i] = sign * x0[p]
                sx1[i] = sign * x1[p]
                g0[i] = gap_on0[p] if off_side == 0 else gap_off0[p]
                g1[i] = gap_on1[p] if off_side == 0 else gap_off1[p]
            side(sx0, sx1, g0, g1, m, h, mom, share, total)
            for i in range(m):
                e = total[i]
                if e > 0.0:
                    p = idx[i]
                    if off_side == 0:
                        p_on[p] = probability(e)
                        when_on[p] = when(share, i, e, u_on[p])
                    else:
                        p_off[p] = probability(e)
                        when_off[p] = when(share, i, e, u_off[p])


@njit(inline="always")
def lane_law(law, itot, lv, la, i):
    """Lane i's two noise components at total photocurrent ``itot`` (A) from ``law``
    (:meth:`gevsim.pixel.noise.NoiseLaw.as_tuple`), as :meth:`~gevsim.pixel.noise.NoiseLaw.components`."""
    shot_q, amp, fc_per_a, fc_max, f_out, read_var, read_rate = law
    beta = 2.0 * math.pi * f_out
    alpha = separate(2.0 * math.pi * min(fc_per_a * itot, fc_max), beta)
    fc = alpha / (2.0 * math.pi)
    lv[0, i] = (shot_q * fc / itot + amp / fc) * beta / (alpha + beta)
    la[0, i] = alpha
    lv[1, i] = read_var
    la[1, i] = read_rate


@njit(inline="always")
def node_exps(b, h, eb):
    """e^(-b tau) at 0, the nodes and h (the covariances' points)."""
    eb[0] = 1.0
    for q in range(NODES):
        eb[1 + q] = _exp(-b * XI[q] * h)
    eb[NODES + 1] = _exp(-b * h)


@njit(inline="never", cache=True, error_model="numpy", fastmath={"nnan", "ninf"})
def lanes(lv, la, m, b, h, eb, c, cp, mom, inv_det):
    """The node moments of m lanes whose components are lv, la (:func:`_covariances`, :func:`_moments`)."""
    _covariances(lv, la, m, b, h, eb, c, cp)
    _moments(c, cp, m, inv_det, mom)


@njit(inline="always")
def probability(e):
    """P(at least one crossing) from the expected number e: 1 - exp(-e)."""
    return 1.0 - _exp(-e)

