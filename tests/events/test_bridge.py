"""Level crossings between two samples (gevsim.events.bridge): against simulated Gaussian bridges, Rice's
stationary rate, and the rule's symmetries."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gevsim.events.bridge import crossings

B = 2 * math.pi * 2000.0  # davis346's output pole
#: (variances, own poles): the photoreceptor's noise at 0.1 chip lux (a slow pole), ~10 lux, and >= 66 lux
#: (its pole capped at 3 kHz), each with davis346's read noise (its 2 kHz pole moved 1 % off the output pole).
LAWS = {
    "slow": ([8e-3, 3e-5], [2 * math.pi * 5.0, 2 * math.pi * 1980.0]),
    "mid": ([7e-4, 3e-5], [2 * math.pi * 450.0, 2 * math.pi * 1980.0]),
    "fast": ([6e-5, 3e-6], [2 * math.pi * 3000.0, 2 * math.pi * 1980.0]),
}


def cov(tau, var, rate):
    tau = np.abs(tau)
    return sum(v * (B * np.exp(-a * tau) - a * np.exp(-B * tau)) / (B - a) for v, a in zip(var, rate))


def columns(values, n):
    return np.asarray(values, float)[:, None] * np.ones(n)


def far(n):
    return np.full(n, 1e3), np.full(n, 1e3)


def random_samples(law, n, gap_low_sd, gap_high_sd, seed):
    """n pairs of samples of ``law``'s noise (independent, each of its stationary spread) and n pairs of gaps
    uniform in [gap_low_sd, gap_high_sd) standard deviations, and the standard deviation."""
    var, _ = LAWS[law]
    rng = np.random.default_rng(seed)
    sd = math.sqrt(sum(var))
    x0, x1 = sd * rng.standard_normal(n), sd * rng.standard_normal(n)
    g0, g1 = sd * rng.uniform(gap_low_sd, gap_high_sd, n), sd * rng.uniform(gap_low_sd, gap_high_sd, n)
    return x0, x1, g0, g1, sd


@pytest.mark.parametrize("law, step_s, level_sd, fall_sd", [
    ("slow", 1e-3, 1.0, 0.0), ("mid", 2.5e-4, 1.0, 0.0), ("mid", 1e-3, 2.0, 0.0), ("mid", 1e-3, 2.0, 1.0),
    ("fast", 2.5e-4, 1.0, 0.0), ("fast", 1e-3, 2.0, 0.0)])
def test_probability_matches_simulated_bridges(law, step_s, level_sd, fall_sd):
    """Paths of the noise on a 201-point grid over the step (exact Gaussian draws from its covariance): the
    fraction that cross a level (falling by fall_sd over the step) with both ends below equals the mean of the
    rule's probability over their ends, within 12 % (the rule's 1 - exp(-E) for the first crossing) and 3
    standard errors (paired)."""
    var, rate = LAWS[law]
    sd = math.sqrt(sum(var))
    n, m = 20000, 201
    t = np.linspace(0.0, step_s, m)
    w, v = np.linalg.eigh(cov(t[:, None] - t[None, :], var, rate))
    x = (v * np.sqrt(np.clip(w, 0.0, None))) @ np.random.default_rng(1).standard_normal((m, n))
    level = sd * (level_sd - fall_sd * t / step_s)
    below = (x[0] < level[0]) & (x[-1] < level[-1])
    crossed = below & ((x - level[:, None]).max(axis=0) >= 0.0)
    p, p_off, _, _ = crossings(x[0], x[-1], (level[0] - x[0], level[-1] - x[-1]), far(n), step_s,
                               columns(var, n), columns(rate, n), B)
    p = np.where(below, p, 0.0)
    assert crossed.mean() > 0.005  # enough crossings to test
    se = float(np.std(crossed - p)) / math.sqrt(n)
    assert abs(p.mean() - crossed.mean()) <= 0.12 * crossed.mean() + 3 * se, (p.mean(), crossed.mean(), se)
    assert np.all(p_off == 0.0)  # the OFF level 1e3 ln away is never integrated


def test_stationary_rate_far_from_the_ends():
    """Over a step much longer than the noise's correlation, with both samples at the mean, the expected
    crossings of a level z sigma up are Rice's nu h exp(-z^2 / 2), nu = sqrt(-C''(0) / C(0)) / 2 pi, less what
    the pinned ends take (~2 correlation times of 10 ms)."""
    var, rate = LAWS["fast"]
    step_s, z = 1e-2, 3.0
    sd = math.sqrt(sum(var))
    nu = math.sqrt(sum(v * a * B for v, a in zip(var, rate)) / sum(var)) / (2 * math.pi)
    p, _, _, _ = crossings([0.0], [0.0], ([z * sd], [z * sd]), far(1), step_s, columns(var, 1), columns(rate, 1), B)
    expected = -math.log1p(-p[0])
    rice = nu * step_s * math.exp(-0.5 * z * z)
    assert 0.95 * rice < expected < rice


def test_symmetries():
    """The OFF side is the ON side of the negated noise; time reversal (swapping the samples and the gaps)
    keeps the probability (every up-crossing between two samples below a level has its down-crossing) to the
    quadrature's accuracy (16 nodes: 7 % where a sample lies within 0.1 sigma of its level); a larger gap never
    raises it."""
    var, rate = LAWS["mid"]
    n = 400
    x0, x1, g0, g1, sd = random_samples("mid", n, 0.05, 3.0, seed=3)
    vk, rk = columns(var, n), columns(rate, n)
    p_on, p_off, _, _ = crossings(x0, x1, (g0, g1), (g0, g1), 5e-4, vk, rk, B)
    q_on, q_off, _, _ = crossings(-x0, -x1, (g0, g1), (g0, g1), 5e-4, vk, rk, B)
    assert np.array_equal(p_on, q_off) and np.array_equal(p_off, q_on)
    r_on, _, _, _ = crossings(x1, x0, (g1, g0), (g1, g0), 5e-4, vk, rk, B)
    assert np.allclose(r_on, p_on, rtol=0.08, atol=1e-9)
    wider, _, _, _ = crossings(x0, x1, (g0 + 0.1 * sd, g1), (g0, g1), 5e-4, vk, rk, B)
    assert np.all(wider <= p_on + 1e-12) and np.all((p_on >= 0.0) & (p_on < 1.0))


def test_skipped_sides_are_negligible():
    """A side the rule does not integrate (its level beyond the noise's reach) would have had a probability
    below 1e-9: integrating every side changes nothing above that."""
    from gevsim.events import _bridge
    var, rate = LAWS["fast"]
    n = 2000
    x0, x1, g0, g1, _ = random_samples("fast", n, 0.0, 15.0, seed=4)
    args = (x0, x1, g0, g1, g1, g0, 5e-4, columns(var, n), columns(rate, n), B)
    outs = []
    for far_sd in (_bridge.Z_SKIP, 1e9):
        out = [np.empty(n) for _ in range(4)]
        _bridge.crossings(*args, *out, np.full(n, 0.5), np.full(n, 0.5), far_sd)
        outs.append(out[:2])
    assert np.mean(outs[0][0] == 0.0) > 0.2  # the gaps reach 15 sigma: many sides are beyond reach
    assert np.all(np.abs(outs[0][0] - outs[1][0]) < 1e-9) and np.all(np.abs(outs[0][1] - outs[1][1]) < 1e-9)


def test_crossing_times_follow_the_sample_near_the_level():
    """A crossing is placed early when the first sample is near the level and the second far below it, late in
    the mirrored case; the time is a fraction of the step."""
    var, rate = LAWS["fast"]
    sd = math.sqrt(sum(var))
    u = np.linspace(0.0, 0.999, 200)
    near, low = np.full(200, 0.2 * sd), np.full(200, 3.0 * sd)
    _, _, w_early, _ = crossings(np.zeros(200), np.zeros(200), (near, low), far(200), 5e-4, columns(var, 200),
                                 columns(rate, 200), B, uniforms=(u, u))
    _, _, w_late, _ = crossings(np.zeros(200), np.zeros(200), (low, near), far(200), 5e-4, columns(var, 200),
                                columns(rate, 200), B, uniforms=(u, u))
    assert np.all((w_early >= 0.0) & (w_early <= 1.0)) and np.all(np.diff(w_early) >= 0.0)
    assert w_early.mean() < 0.35 and w_late.mean() > 0.6  # up-crossings come early in a bridge


@pytest.mark.parametrize("kwargs, match", [
    ({"step_s": 0.0}, "step_s"), ({"var": [[-1.0]]}, "variances"), ({"rate": [[B]]}, "output pole"),
    ({"x1": [0.0, 0.0]}, "differ in size")])
def test_bad_input_is_named(kwargs, match):
    args = {"x0": [0.0], "x1": [0.0], "gap_on": ([0.1], [0.1]), "gap_off": ([0.1], [0.1]), "step_s": 5e-4,
            "var": [[1e-4]], "rate": [[100.0]], "output_pole_rad_s": B} | kwargs
    with pytest.raises(ValueError, match=match):
        crossings(**args)
