"""Prototype: the Rice bridge on the gradient comparators (issue 37, item 1), against the driver's short steps.

A gradient comparator compares G = v(A) - v(B) (two neighbouring pixels' outputs, less its offset) with +-Theta.
Sampled at long steps it misses the excursions between the samples: a comparator at 0 at both samples may have
gone above Theta and back (two events), one at +-1 may have dipped to 0 and back. G's noise is the difference of
two pixels' independent noises, a sum of three white noises through two poles each (each pixel's photoreceptor
pole at its own photocurrent and the read noise of both, which share a pole), so the bridge's crossing rate is
Rice's formula on it (:func:`gevsim.events.bridge.crossings`, with three components) given G's noise at both
samples (v minus the noise-free twin's output).

This prototype runs in Python, one step at a time: for every comparator whose state is the same at both samples
it takes the expected number of excursions E of each open side from the rule (E = -ln(1 - p)), draws N ~ Poisson(E)
and counts 2N events. A comparator that changes between 0 and +-1 shows one crossing at the samples; the path may
have crossed 2k + 1 times: it takes Rice's expected up-crossings E of that level (:func:`expected_upcrossings`, any
gaps) and counts 2N more, N ~ Poisson(E - 1) (--samples-only-changes leaves this out). A change from +1 to -1 or
back (two levels) takes no extra. Either E is capped by :func:`cap` (a bound; the table says how often it bit). It compares events per comparator per second with the driver's 20-us steps on a static
log-normal texture (davis346, the driver's thresholds 0.05/0.1/0.2 ln, comparator offsets, no hysteresis). Its
time is not the rule's cost (Python per step); it prints the share of comparator-steps within the rule's reach,
which with the kernel's ~0.3 us per lane sets that cost.

    PYTHONPATH=benchmarks .venv/bin/python benchmarks/gradient_bridge.py [--lux 0.1 10 1000] [--steps-us 500 2000]
        [--ref-us 20] [--samples-only-changes]
"""

from __future__ import annotations

import argparse
import copy
import math
import time

import numpy as np
from bridge_crossings import lighting, rate, scene
from bridged_dvs import started

from gevsim.emulation.emulators import GradientConfig
from gevsim.events import GradientEmulator, _bridge
from gevsim.events.bridge import FAR_SD, crossings
from gevsim.pixel import load_preset

REF_STEP_S = 2e-5
#: Also count the extra crossings of the comparators that change state between the samples (--samples-only-changes
#: leaves them out).
CHANGED = True


def comparator_counts(events: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """Events per comparator, (2, H, W)."""
    h, w = shape
    flat = events["axis"].astype(np.int64) * h * w + events["y"].astype(np.int64) * w + events["x"]
    return np.bincount(flat, minlength=2 * h * w).reshape(2, h, w).astype(float)


def valid(shape: tuple[int, int]) -> np.ndarray:
    """The comparators that exist (X: all but the last column; Y: all but the last row), (2, H, W)."""
    m = np.ones((2,) + shape, bool)
    m[0, :, -1] = False
    m[1, -1, :] = False
    return m


def pairs(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-pixel field a (H, W) at each comparator's pixels A (the neighbour) and B (its own), each (2, H, W)."""
    xa = np.zeros((2,) + a.shape)
    xa[0, :, :-1] = a[:, 1:]
    xa[1, :-1, :] = a[1:, :]
    return xa, np.broadcast_to(a, (2,) + a.shape)


def bridged_counts(pr, twin, grad, light, t0: float, span_s: float, h: float, rng, law) -> tuple[np.ndarray, float]:
    """Per-comparator counts of the sampled events plus the rule's excursions; the share of comparator-steps
    within reach."""
    shape = grad.shape
    ok = valid(shape)
    counts = np.zeros((2,) + shape)
    mu_prev = twin.process(light(np.array([t0 + 1e-6]), 1e-6), np.array([t0 + 1e-6]))[0]
    v_prev = pr.process(light(np.array([t0 + 1e-6]), 1e-6), np.array([t0 + 1e-6]))[0]
    grad.process(v_prev[None], np.array([t0 + 1e-6]))
    t = t0 + 1e-6 + h * np.arange(1, int(round(span_s / h)) + 1)
    beta = 2.0 * math.pi * law.output_pole_hz
    reach_n = 0
    for tt in t:
        cur = light(np.array([tt]), h)
        v = pr.process(cur, np.array([tt]))[0]
        mu = twin.process(cur, np.array([tt]))[0]
        s0, g0 = grad.state.copy(), grad.g_prev.copy()
        counts += comparator_counts(grad.process(v[None], np.array([tt])), shape)
        s1, g1 = grad.state, grad.g_prev
        var, pole = law.components(cur[0].reshape(-1) * pr.gain + pr.dark_a)
        xa0, xb0 = pairs(v_prev - mu_prev)
        xa1, xb1 = pairs(v - mu)
        va, vb = pairs(var[0].reshape(shape))
        ra, rb = pairs(pole[0].reshape(shape))
        open_ = ok & (s0 == s1)
        th = grad.theta
        up0 = np.where(s0 == 1, -1.0, np.where(s0 == 0, th - g0, -th - g0))
        up1 = np.where(s0 == 1, -1.0, np.where(s0 == 0, th - g1, -th - g1))
        dn0 = np.where(s0 == -1, -1.0, np.where(s0 == 0, g0 + th, g0 - th))
        dn1 = np.where(s0 == -1, -1.0, np.where(s0 == 0, g1 + th, g1 - th))
        sel = np.flatnonzero(open_)
        x0 = (xa0 - xb0).reshape(-1)[sel]
        x1 = (xa1 - xb1).reshape(-1)[sel]
        comp_var = np.stack([va.reshape(-1)[sel], vb.reshape(-1)[sel], np.full(sel.size, 2 * law.read_var_ln2)])
        comp_rate = np.stack([ra.reshape(-1)[sel], rb.reshape(-1)[sel], np.full(sel.size, law.read_rate_rad_s)])
        sd = np.sqrt(comp_var.sum(0))
        reach = 1.5 * np.maximum(abs(x0), abs(x1)) + FAR_SD * sd
        gaps = [a.reshape(-1)[sel] for a in (up0, up1, dn0, dn1)]
        near = ((np.minimum(gaps[0] + x0, gaps[1] + x1) < reach) & (gaps[0] > 0) & (gaps[1] > 0)) | (
            (np.minimum(gaps[2] - x0, gaps[3] - x1) < reach) & (gaps[2] > 0) & (gaps[3] > 0))
        reach_n += int(near.sum())
        tick = time.perf_counter()
        p_up, p_dn, _, _ = crossings(x0, x1, (gaps[0], gaps[1]), (gaps[2], gaps[3]), h, comp_var, comp_rate, beta)
        RULE[0] += time.perf_counter() - tick
        RULE[1] += int(near.sum())
        e_cap = cap(comp_var, comp_rate, beta, h)
        e_up, e_dn = (-np.log1p(-np.minimum(p, 1 - 1e-15)) for p in (p_up, p_dn))
        CAPPED[0] += int(np.sum(e_up > e_cap) + np.sum(e_dn > e_cap))
        CAPPED[1] += 2 * e_up.size
        e = np.minimum(e_up, e_cap) + np.minimum(e_dn, e_cap)
        flat = counts.reshape(-1)
        flat[sel] += 2 * rng.poisson(e)
        if CHANGED:  # comparators that change between 0 and +-1: the crossings beyond the one the samples show
            for old, new, level_sign, up in ((0, 1, 1, True), (0, -1, -1, False), (1, 0, 1, False), (-1, 0, -1, True)):
                sel = np.flatnonzero(ok & (s0 == old) & (s1 == new))
                if sel.size == 0:
                    continue
                level = (level_sign * th).reshape(-1)[sel]
                ga, gb = g0.reshape(-1)[sel], g1.reshape(-1)[sel]
                x0 = (xa0 - xb0).reshape(-1)[sel]
                x1 = (xa1 - xb1).reshape(-1)[sel]
                sign = 1.0 if up else -1.0
                cv = np.stack([va.reshape(-1)[sel], vb.reshape(-1)[sel], np.full(sel.size, 2 * law.read_var_ln2)])
                cr = np.stack([ra.reshape(-1)[sel], rb.reshape(-1)[sel], np.full(sel.size, law.read_rate_rad_s)])
                e = expected_upcrossings(sign * x0, sign * x1, sign * (level - ga), sign * (level - gb), cv, cr, beta, h)
                e_cap = cap(cv, cr, beta, h)
                CAPPED[0] += int(np.sum(e > e_cap))
                CAPPED[1] += e.size
                e = np.minimum(e, e_cap)
                flat[sel] += 2 * rng.poisson(np.maximum(e - 1.0, 0.0))
        v_prev, mu_prev = v, mu
    return counts, reach_n / (ok.sum() * len(t))


def expected_upcrossings(x0, x1, g0, g1, var, pole, beta, h):
    """Rice's expected up-crossings of the level x + g (a straight line in time) by the bridge from x0 to x1, for any
    gaps (the kernel's :func:`gevsim.events._bridge.side` takes positive gaps only): numpy over the lanes, with the
    kernel's node moments (:func:`gevsim.events._bridge.lanes`)."""
    m = x0.size
    if m == 0:
        return np.zeros(0)
    n = _bridge.NODES
    eb, c, cp = np.empty(n + 2), np.empty((n + 2, m)), np.empty((n + 2, m))
    mom, inv_det = np.empty((7, n, m)), np.empty(m)
    _bridge.node_exps(beta, h, eb)
    _bridge.lanes(np.ascontiguousarray(var), np.ascontiguousarray(pole), m, beta, h, eb, c, cp, mom, inv_det)
    b0 = x0 + g0
    slope = (x1 + g1 - b0) / h
    total = np.zeros(m)
    for q in range(n):
        gap = b0 + slope * _bridge.XI[q] * h - (mom[0, q] * x0 + mom[1, q] * x1)
        z = gap * mom[2, q]
        mu = mom[3, q] * x0 + mom[4, q] * x1 + mom[5, q] * gap - slope
        s = mom[6, q]
        u = mu / s
        cdf = 0.5 * (1.0 + np.vectorize(math.erf)(u / math.sqrt(2.0)))
        excess = s * (u * cdf + np.exp(-0.5 * u * u) / math.sqrt(2 * math.pi))
        total += _bridge.WEIGHT[q] * h * np.exp(-0.5 * z * z) / math.sqrt(2 * math.pi) * mom[2, q] * excess
    return total


def cap(var, pole, beta, h):
    """A bound on the expected crossings of a level over one step: each end contributes at most ~1 (a sample at its
    level crosses at once or not), and in between no faster than the fastest component's own zero-crossing rate,
    sqrt(a_k beta) / 2 pi (Rice, for a white noise through poles a_k and beta). The 16-node quadrature exceeds it
    only when a sample sits within microns of its level (a start 4.6e-6 ln below it gave E = 17,362)."""
    fastest = np.max(np.where(var > 0.0, np.sqrt(pole * beta), 0.0), axis=0)
    return 2.0 + h * fastest / (2.0 * math.pi)


CAPPED = [0, 0]
#: Seconds in the rule's kernel (the serial API kernel, K = 3) and the lanes it integrated.
RULE = [0.0, 0]


def reference_counts(pr, grad, light, t0: float, span_s: float) -> np.ndarray:
    shape = grad.shape
    tt = np.array([t0 + 1e-6])
    grad.process(pr.process(light(tt, 1e-6), tt), tt)
    t = t0 + 1e-6 + REF_STEP_S * np.arange(1, int(round(span_s / REF_STEP_S)) + 1)
    counts = np.zeros((2,) + shape)
    for a in range(0, len(t), 500):
        tt = t[a:a + 500]
        counts += comparator_counts(grad.process(pr.process(light(tt, REF_STEP_S), tt), tt), shape)
    return counts


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--lux", type=float, nargs="*", default=[0.1, 10.0, 1000.0])
    ap.add_argument("--steps-us", type=float, nargs="*", default=[500.0, 2000.0])
    ap.add_argument("--span", type=float, default=0.5)
    ap.add_argument("--size", type=int, default=32)
    ap.add_argument("--ref-us", type=float, default=20.0, help="the reference's step (us)")
    ap.add_argument("--samples-only-changes", action="store_true",
                    help="leave out the extra crossings of comparators that change state between the samples")
    args = ap.parse_args()
    global CHANGED, REF_STEP_S
    CHANGED, REF_STEP_S = not args.samples_only_changes, args.ref_us * 1e-6
    preset = load_preset("davis346")
    shape = (args.size, args.size)
    ok = valid(shape)
    changes = "sample changes only" if args.samples_only_changes else "with changes"
    print(f"davis346 {args.size}x{args.size}, {changes}, static, {args.span:g} s; gradient events per comparator per second "
          "(95 % over comparators)")
    print(f"| chip lux | {args.ref_us:g} us | h | sampled only | sampled + bridge | bridged / reference "
          "| within reach | sides capped |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    for lux in args.lux:
        level = scene(shape, preset, lux)
        light = lighting(level, 0.0, 0.0, 5.0)
        pr, bridging, _, t0 = started(preset, level, REF_STEP_S, light)
        grad = GradientEmulator(shape, thresholds_ln=GradientConfig.thresholds_ln, rng=np.random.default_rng(3),
                                offset_sigma_ln=preset.events.comparator_offset_v / preset.photoreceptor.volts_per_ln)
        ref = reference_counts(copy.deepcopy(pr), copy.deepcopy(grad), light, t0, args.span)
        r_ref = rate(ref[ok], args.span)
        law = pr.noise_law()
        for h_us in args.steps_us:
            h = h_us * 1e-6
            br, share = bridged_counts(copy.deepcopy(pr), copy.deepcopy(bridging.twin), copy.deepcopy(grad), light, t0,
                                       args.span, h, np.random.default_rng(5), law)
            sampled = copy.deepcopy(grad)
            smp = np.zeros((2,) + shape)
            p2 = copy.deepcopy(pr)
            tt = np.array([t0 + 1e-6])
            sampled.process(p2.process(light(tt, 1e-6), tt), tt)
            t = t0 + 1e-6 + h * np.arange(1, int(round(args.span / h)) + 1)
            smp += comparator_counts(sampled.process(p2.process(light(t, h), t), t), shape)
            r_s, r_b = rate(smp[ok], args.span), rate(br[ok], args.span)
            print(f"| {lux:g} | {r_ref[0]:.1f} ± {r_ref[1]:.1f} | {h_us:g} us | {r_s[0]:.1f} ± {r_s[1]:.1f} | "
                  f"{r_b[0]:.1f} ± {r_b[1]:.1f} | {r_b[0] / r_ref[0]:.3f} | {share:.2f} | {CAPPED[0]} of {CAPPED[1]} |",
                  flush=True)
            print(f"    rule kernel: {RULE[0] * 1e6 / max(RULE[1], 1):.2f} us per lane within reach, "
                  f"{RULE[0] / args.span / ok.sum():.2e} s per comparator per simulated second", flush=True)
            CAPPED[:] = [0, 0]
            RULE[:] = [0.0, 0]


if __name__ == "__main__":
    main()
