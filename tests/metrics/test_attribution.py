"""Flicker attribution: coverage of the intervals, the phase-locked estimator and its null."""

import math

import numpy as np
import pytest
from scipy import stats

from gevsim.metrics.attribution import mean_interval, phase_locked_rate, ratio_interval

PERIOD_S, DURATION_S, PIXELS = 0.01, 0.2, 100


def modulated_events(rng, background, amplitude, harmonic=1):
    """Poisson events at rate background + amplitude cos(2 pi m phi) per pixel (phi: lamp phase)."""
    n = rng.poisson(background * PIXELS * DURATION_S)
    phases = np.empty(0)
    while phases.size < n:  # rejection sampling of the phase density
        phi = rng.random(2 * n + 10)
        keep = rng.random(phi.size) * (background + abs(amplitude)) < background + amplitude * np.cos(
            2 * np.pi * harmonic * phi)
        phases = np.concatenate([phases, phi[keep]])
    periods = rng.integers(0, round(DURATION_S / PERIOD_S), n)
    return (periods + phases[:n]) * PERIOD_S


def test_phase_locked_rms_is_recovered_within_its_interval_in_most_seeds():
    """r(phi) = 50 + 20 cos(2 pi phi) ev/px/s: the modulation's RMS over the period is 20 / sqrt 2."""
    truth = 20.0 / math.sqrt(2.0)
    hits, estimates = 0, []
    for seed in range(100):
        rng = np.random.default_rng(seed)
        t = modulated_events(rng, 50.0, 20.0)
        res = phase_locked_rate(t, period_s=PERIOD_S, duration_s=DURATION_S, n_pixels=PIXELS, n_boot=200, seed=seed)
        hits += res.rms.low <= truth <= res.rms.high
        estimates.append(res.rms.estimate)
        assert res.mean_rate == pytest.approx(len(t) / PIXELS / DURATION_S)
    assert hits >= 90
    assert np.mean(estimates) == pytest.approx(truth, rel=0.05)


def test_phase_locked_estimate_finds_higher_harmonics_and_rejects_the_null_only_when_locked():
    rng = np.random.default_rng(1)
    locked = phase_locked_rate(modulated_events(rng, 50.0, 20.0, harmonic=3), period_s=PERIOD_S,
                               duration_s=DURATION_S, n_pixels=PIXELS, n_boot=200)
    # The Z^2_M p-value is exact in its tail: far below the 1/(n_boot + 1) floor of simulated nulls.
    assert locked.p_value < 1e-6 and np.argmax(np.abs(locked.harmonics)) == 2
    nulls = []
    for seed in range(200):
        flat = modulated_events(np.random.default_rng(100 + seed), 50.0, 0.0)
        nulls.append(phase_locked_rate(flat, period_s=PERIOD_S, duration_s=DURATION_S, n_pixels=PIXELS, n_boot=20,
                                       seed=seed).p_value)
    # Under the null the p-value is uniform on [0, 1] (Kolmogorov-Smirnov), so 5 % fall below 0.05.
    assert stats.kstest(nulls, "uniform").pvalue > 0.001
    assert sum(p < 0.05 for p in nulls) <= 19  # binomial(200, 0.05) p99.9 ~ 20


def test_mean_interval_covers_and_shrinks_with_repeats():
    truth = 3.0
    for repeats in (3, 10):
        hits = sum(mean_interval(np.random.default_rng(s).normal(truth, 2.0, repeats)).low <= truth <=
                   mean_interval(np.random.default_rng(s).normal(truth, 2.0, repeats)).high for s in range(200))
        assert hits >= 180  # 95 % nominal
    widths = [np.mean([(lambda iv: iv.high - iv.low)(mean_interval(np.random.default_rng(s).normal(0, 1, r)))
                       for s in range(50)]) for r in (2, 4, 8, 16)]
    assert all(b < a for a, b in zip(widths, widths[1:]))
    one = mean_interval([5.0])
    assert one.low == -math.inf and one.high == math.inf


def test_fieller_interval_covers_a_ratio_of_paired_means():
    hits = 0
    for s in range(200):
        rng = np.random.default_rng(s)
        common = rng.normal(0, 1.0, 6)  # paired repeats share a seed: correlated numerator and denominator
        num = 40.0 + 3.0 * common + rng.normal(0, 1.0, 6)
        den = 10.0 + 1.0 * common + rng.normal(0, 0.5, 6)
        iv = ratio_interval(num, den)
        hits += iv.low <= 4.0 <= iv.high
    assert hits >= 180
    unbounded = ratio_interval([1.0, 2.0, 3.0], [-1.0, 0.5, 0.6])  # denominator indistinguishable from zero
    assert unbounded.method == "fieller (unbounded)" and unbounded.includes_zero


def test_formatting_never_shows_a_bare_negative_estimate():
    iv = mean_interval([-3.0, 1.0, -2.0])
    assert iv.estimate < 0 and iv.format().startswith("not distinguishable from zero (")
    assert mean_interval([10.0, 11.0, 12.0]).format() == "11 [8.52, 13.5]"
    with pytest.raises(ValueError, match="confidence"):
        mean_interval([1.0, 2.0], confidence=1.5)
