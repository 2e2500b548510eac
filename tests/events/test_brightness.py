"""DVS emulator: analytic event counts and times, refractory, leak, symmetry, chunking."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gevsim.events import BrightnessEmulator
from gevsim.pixel import EventParams

SHAPE = (3, 4)


def emulate(v, t, params=EventParams(), seed=0, shape=SHAPE):
    em = BrightnessEmulator(shape, params, rng=np.random.default_rng(seed))
    return em.process(v, t)


def ramp(total, n=101, duration=1e-3, shape=SHAPE):
    t = np.linspace(0.0, duration, n)
    return np.linspace(0.0, total, n)[:, None, None] * np.ones((1,) + shape), t


@pytest.mark.parametrize("total, theta", [(1.05, 0.2), (0.99, 0.1), (-0.7, 0.15), (3.0, 0.3)])
def test_ramp_gives_floor_d_over_theta_events_at_the_crossing_times(total, theta):
    v, t = ramp(total)
    ev = emulate(v, t, EventParams(threshold_on_ln=theta, threshold_off_ln=theta))
    n = math.floor(abs(total) / theta + 1e-9)
    assert len(ev) == n * SHAPE[0] * SHAPE[1]
    one = ev[(ev["x"] == 1) & (ev["y"] == 2)]
    expected_us = np.floor(1e3 * theta * np.arange(1, n + 1) / abs(total) + 0.5)  # 1 ms ramp
    np.testing.assert_array_equal(one["t"], expected_us)
    assert np.all(one["p"] == (total > 0))
    assert np.all(np.diff(ev["t"]) >= 0)


def test_several_events_in_one_step():
    ev = emulate(np.array([0.0, 1.0])[:, None, None] * np.ones((1,) + SHAPE), [0.0, 1e-3],
                 EventParams(threshold_on_ln=0.19))
    one = ev[(ev["x"] == 0) & (ev["y"] == 0)]
    np.testing.assert_array_equal(one["t"], [190, 380, 570, 760, 950])


def test_refractory_period_delays_and_merges_events():
    v, t = ramp(1.0, n=1001, duration=1e-3)  # crossings every 200 us without refractory
    ev = emulate(v, t, EventParams(refractory_s=300e-6))
    one = ev[(ev["x"] == 0) & (ev["y"] == 0)]
    assert one["t"].tolist() == [200, 700]  # 300 us held in reset, then 200 us to the next threshold


@pytest.mark.parametrize("slope_ln_s, refractory_s, theta", [(2000.0, 100e-6, 0.2), (1000.0, 50e-6, 0.1),
                                                              (-3000.0, 20e-6, 0.15), (500.0, 1e-3, 0.2)])
def test_refractory_law_on_a_ramp(slope_ln_s, refractory_s, theta):
    """The change amplifier is held in reset for the refractory period and forgets what changed
    meanwhile: a ramp of slope k gives events refractory + theta / |k| apart (Lichtsteiner, Posch &
    Delbruck 2008), not max(refractory, theta / |k|)."""
    duration = 0.02
    t = np.linspace(0.0, duration, 4001)
    v = (slope_ln_s * t)[:, None, None] * np.ones((1,) + SHAPE)
    ev = emulate(v, t, EventParams(threshold_on_ln=theta, threshold_off_ln=theta, refractory_s=refractory_s))
    one = ev[(ev["x"] == 1) & (ev["y"] == 2)]
    expected_us = (refractory_s + theta / abs(slope_ln_s)) * 1e6
    assert len(one) == math.floor((duration - theta / abs(slope_ln_s)) * 1e6 / expected_us + 1e-9) + 1
    np.testing.assert_allclose(np.diff(one["t"]), expected_us, atol=1.0)  # timestamps are whole us
    assert np.all(one["p"] == (slope_ln_s > 0))


def test_changes_during_refractory_are_forgotten():
    """A rise fires ON at 0.2 (t = 100 us); the level follows the signal while held for 200 us, so
    at release (300 us) it is the signal's 0.3375, and the next event is the OFF at 0.1375 (t =
    620 us), not one counted from the pre-refractory level."""
    t = np.array([0.0, 200e-6, 1000e-6])
    v = np.array([0.0, 0.4, -0.1])[:, None, None] * np.ones((1,) + SHAPE)
    ev = emulate(v, t, EventParams(refractory_s=200e-6))
    one = ev[(ev["x"] == 0) & (ev["y"] == 0)]
    assert one["p"].tolist() == [True, False]
    assert one["t"].tolist() == [100, 620]


def test_reset_noise_spreads_the_intervals_on_a_ramp():
    """Each release from reset leaves the level off by a N(0, sigma) error: on a ramp of slope k the
    intervals have mean theta / k and standard deviation sigma / k."""
    k, theta, sigma = 1000.0, 0.2, 0.02
    shape = (40, 50)
    t = np.linspace(0.0, 0.05, 2001)
    v = (k * t)[:, None, None] * np.ones((1,) + shape)
    ev = emulate(v, t, EventParams(reset_noise_ln=sigma), shape=shape)
    order = np.lexsort((ev["t"], ev["x"], ev["y"]))
    e = ev[order]
    same = (e["x"][1:] == e["x"][:-1]) & (e["y"][1:] == e["y"][:-1])
    gaps = np.diff(e["t"])[same] * 1e-6
    assert len(gaps) > 10_000
    assert gaps.mean() == pytest.approx(theta / k, rel=0.01)
    assert gaps.std() == pytest.approx(sigma / k, rel=0.05)


def test_reset_noise_frees_the_rates_from_the_first_sample():
    """Without reset noise a pixel's level stays on a lattice of whole thresholds from its first
    sample, so the rate of noise events depends on where that sample fell; with reset noise it
    does not (sensor-physics audit, section 5b)."""
    rng = np.random.default_rng(5)
    shape, n = (40, 50), 4000
    t = 1e-5 * np.arange(n)
    noise = np.empty((n,) + shape)  # a stationary AR(1) noise of sigma 0.04 ln around 0
    a = rng.normal(0.0, 0.04, shape)
    for i in range(n):
        a = 0.9 * a + math.sqrt(1 - 0.81) * rng.normal(0.0, 0.04, shape)
        noise[i] = a
    start = rng.uniform(0.0, 0.1, shape)  # where the first sample sits on the 0.1 ln lattice
    v = np.concatenate([start[None], noise[1:]])
    theta = 0.1

    def spread(sigma):
        ev = emulate(v, t, EventParams(threshold_on_ln=theta, threshold_off_ln=theta, reset_noise_ln=sigma),
                     shape=shape)
        counts = np.zeros(shape)
        np.add.at(counts, (ev["y"], ev["x"]), 1)
        bins = np.digitize(start, [0.025, 0.05, 0.075])
        per_bin = np.array([counts[bins == b].mean() for b in range(4)])
        return per_bin.max() / max(per_bin.min(), 1e-9), counts.mean()

    frozen, _ = spread(0.0)
    free, mean = spread(0.05)
    assert mean > 20  # events per pixel: per-bin means known to ~1 %
    assert frozen > 1.4 and free < 1.1  # measured 1.65 and 1.05


def test_leak_rate():
    rate_hz = 50.0
    n, duration = 2001, 1.0
    v = np.zeros((n,) + (20, 20))
    ev = emulate(v, np.linspace(0, duration, n), EventParams(leak_rate_hz=rate_hz), shape=(20, 20))
    assert np.all(ev["p"])  # leak events are ON events
    assert len(ev) / (400 * duration) == pytest.approx(rate_hz, rel=0.02)


@pytest.mark.parametrize("cold_start", [False, True])
def test_a_running_sensor_leaks_at_its_steady_rate_from_the_start(cold_start):
    """Leak phases are uniform (issue 22): over the first second a static scene gives the steady
    leak rate, within 10 %, not nothing until 1 / rate. The lognormal spread leaves no pixel at 0."""
    shape, rate_hz = (100, 100), 0.8
    t = np.linspace(0.0, 1.0, 101)
    em = BrightnessEmulator(shape, EventParams(leak_rate_hz=rate_hz, leak_rate_spread=0.5),
                            rng=np.random.default_rng(4), cold_start=cold_start)
    ev = em.process(np.zeros((len(t),) + shape), t)
    expected = em.leak_ln_per_s.sum() / 0.2  # sum of the pixels' rates (Hz) over one second
    assert np.all(em.leak_ln_per_s > 0)
    assert expected == pytest.approx(rate_hz * shape[0] * shape[1], rel=0.02)
    if cold_start:
        assert len(ev) < 0.5 * expected  # only pixels faster than 1 Hz leak within the first second
    else:
        assert len(ev) == pytest.approx(expected, rel=0.1)


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 2**31 - 1))
def test_negating_the_input_swaps_polarities(seed):
    rng = np.random.default_rng(seed)
    v = np.cumsum(rng.normal(0, 0.1, (30,) + SHAPE), axis=0)
    t = 1e-4 * np.arange(30)
    a, b = emulate(v, t), emulate(-v, t)
    np.testing.assert_array_equal(a[["x", "y", "t"]], b[["x", "y", "t"]])
    np.testing.assert_array_equal(a["p"], ~b["p"])


def test_chunked_equals_one_shot_bit_for_bit():
    rng = np.random.default_rng(3)
    shape = (40, 50)
    v = np.cumsum(rng.normal(0, 0.08, (120,) + shape), axis=0).astype(np.float32)
    t = np.cumsum(rng.uniform(1e-6, 2e-6, 120))  # steps of 1-2 us: several events share a microsecond
    p = EventParams(threshold_mismatch_ln=0.03, refractory_s=3e-6, leak_rate_hz=100.0, leak_rate_spread=0.5)
    one = emulate(v, t, p, shape=shape)
    em = BrightnessEmulator(shape, p, rng=np.random.default_rng(0))
    cuts = [0, 1, 2, 40, 41, 97, 120]
    parts = np.concatenate([em.process(v[a:b], t[a:b]) for a, b in zip(cuts, cuts[1:])])
    assert len(one) > 1000
    np.testing.assert_array_equal(one, parts)


def test_mismatch_is_a_seeded_fixed_pattern():
    p = EventParams(threshold_mismatch_ln=0.03)
    a = BrightnessEmulator((100, 100), p, rng=np.random.default_rng(1))
    b = BrightnessEmulator((100, 100), p, rng=np.random.default_rng(1))
    c = BrightnessEmulator((100, 100), p, rng=np.random.default_rng(2))
    assert np.array_equal(a.threshold_on_ln, b.threshold_on_ln)
    assert not np.array_equal(a.threshold_on_ln, c.threshold_on_ln)
    assert a.threshold_on_ln.std() == pytest.approx(0.03, rel=0.05)


def test_events_have_tonic_dtype():
    v, t = ramp(0.5)
    ev = emulate(v, t)
    assert ev.dtype.names == ("x", "y", "t", "p")
    assert (ev.dtype["x"], ev.dtype["t"], ev.dtype["p"]) == (np.dtype("i2"), np.dtype("i8"), np.dtype("?"))


@pytest.mark.parametrize(
    "v, t, match",
    [
        (np.full((2,) + SHAPE, np.nan), [0.0, 1e-3], "finite"),
        (np.zeros((2,) + SHAPE), [1e-3, 0.0], "increase strictly"),
        (np.zeros((2, 4, 3)), [0.0, 1e-3], r"shape \(T, 3, 4\)"),
        (np.zeros((3,) + SHAPE), [0.0, 1e-3], "2 times"),
    ],
)
def test_bad_input(v, t, match):
    em = BrightnessEmulator(SHAPE, EventParams(), rng=np.random.default_rng(0))
    with pytest.raises(ValueError, match=match):
        em.process(v, t)


def test_time_must_continue_across_chunks():
    em = BrightnessEmulator(SHAPE, EventParams(), rng=np.random.default_rng(0))
    em.process(np.zeros((2,) + SHAPE), [0.0, 1e-3])
    with pytest.raises(ValueError, match="increase strictly"):
        em.process(np.zeros((1,) + SHAPE), [1e-3])


