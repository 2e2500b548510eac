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
    v, t = ramp(1.0, n=1001, duration=1e-3)  # crossings every 200 us
    ev = emulate(v, t, EventParams(refractory_s=300e-6))
    one = ev[(ev["x"] == 0) & (ev["y"] == 0)]
    gaps = np.diff(one["t"])
    assert len(one) < 5 and np.all(gaps >= 300)
    assert one["t"][0] == 200


def test_leak_rate():
    rate_hz = 50.0
    n, duration = 2001, 1.0
    v = np.zeros((n,) + (20, 20))
    ev = emulate(v, np.linspace(0, duration, n), EventParams(leak_rate_hz=rate_hz), shape=(20, 20))
    assert np.all(ev["p"])  # leak events are ON events
    assert len(ev) / (400 * duration) == pytest.approx(rate_hz, rel=0.02)


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


def test_an_off_crossing_after_a_lapsed_refractory_on_is_on_time():
    """A rise fires ON at 0.2 (t = 100 us), a second ON is held by a 200 us refractory period, the
    signal falls meanwhile: the OFF crossing inside the same step is stamped at its own time."""
    t = np.array([0.0, 200e-6, 1000e-6])
    v = np.array([0.0, 0.4, -0.1])[:, None, None] * np.ones((1,) + SHAPE)
    ev = emulate(v, t, EventParams(refractory_s=200e-6))
    one = ev[(ev["x"] == 0) & (ev["y"] == 0)]
    # ON at 100 us resets the level to 0.2; the pending second ON lapses at 300 us (the signal
    # has fallen below 0.4); the signal (0.4 at 200 us, -0.5 per 800 us) reaches 0.0, one OFF
    # step below the level, at 200 + 0.8 * 800 = 840 us.
    assert one["p"].tolist() == [True, False]
    assert one["t"].tolist() == [100, 840]
