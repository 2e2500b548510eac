"""Brightness-event reconstruction baselines: analytic step sums and filter responses."""

import math
import time

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gevsim.events.types import BRIGHTNESS_DTYPE
from gevsim.reconstruct.brightness import (
    COMPLEMENTARY_CUTOFF_RAD_S,
    HIGH_PASS_CUTOFF_RAD_S,
    EventFilter,
    complementary_filter,
    direct_integration,
    high_pass_filter,
)

W, H = 5, 4


def events(rows):
    """Events from (x, y, t_us, on) rows."""
    ev = np.zeros(len(rows), BRIGHTNESS_DTYPE)
    for i, (x, y, t, p) in enumerate(rows):
        ev[i] = (x, y, t, p)
    return ev


def test_default_cutoffs_are_the_authors_code_defaults_in_rad_s():
    assert HIGH_PASS_CUTOFF_RAD_S == pytest.approx(2 * math.pi * 0.1)
    assert COMPLEMENTARY_CUTOFF_RAD_S == pytest.approx(2 * math.pi * 0.5)


def test_direct_integration_is_the_exact_step_sum_at_each_frame_time():
    ev = events([(1, 2, 10, True), (1, 2, 20, True), (3, 0, 25, False), (1, 2, 30, False), (3, 0, 40, False)])
    out = direct_integration(ev, [5, 20, 35, 40], width=W, height=H, contrast_on_ln=0.3, contrast_off_ln=0.1)
    assert out.shape == (4, H, W) and out.dtype == np.float64
    assert out[:, 2, 1].tolist() == [0.0, 0.6, 0.5, 0.5]  # event at t=20 counts at frame t=20
    assert out[:, 0, 3].tolist() == [0.0, 0.0, -0.1, -0.2]
    untouched = np.ones((H, W), bool)
    untouched[2, 1] = untouched[0, 3] = False
    assert np.all(out[:, untouched] == 0.0)


def test_direct_integration_adds_the_initial_image():
    init = np.arange(H * W, dtype=float).reshape(H, W)
    ev = events([(0, 0, 1, True)])
    out = direct_integration(ev, [2], width=W, height=H, initial=init)
    expected = init.copy()
    expected[0, 0] += 0.2
    np.testing.assert_array_equal(out[0], expected)


def test_high_pass_decays_as_exp_minus_alpha_dt_after_one_event():
    alpha, c = 7.0, 0.25
    ev = events([(2, 1, 0, True)])
    t = np.array([0, 1000, 50_000, 200_000, 1_000_000])
    out = high_pass_filter(ev, t, width=W, height=H, contrast_on_ln=c, contrast_off_ln=c, cutoff_rad_s=alpha)
    np.testing.assert_allclose(out[:, 1, 2], c * np.exp(-alpha * t * 1e-6), rtol=1e-12)


def test_high_pass_sums_decayed_steps_of_both_polarities():
    alpha = 3.0
    ev = events([(0, 0, 0, True), (0, 0, 100_000, False), (0, 0, 250_000, True)])
    t_out = 400_000
    out = high_pass_filter(ev, [t_out], width=W, height=H, contrast_on_ln=0.2, contrast_off_ln=0.15, cutoff_rad_s=alpha)
    expected = sum(c * math.exp(-alpha * (t_out - ti) * 1e-6) for ti, c in [(0, 0.2), (100_000, -0.15), (250_000, 0.2)])
    assert out[0, 0, 0] == pytest.approx(expected, rel=1e-12)


def test_high_pass_constant_event_rate_reaches_analytic_steady_state():
    alpha, c, period_us = 20.0, 0.1, 10_000  # 100 ON events/s for 2 s (40 time constants)
    n = 200
    ev = events([(4, 3, k * period_us, True) for k in range(n)])
    t_last = (n - 1) * period_us
    out = high_pass_filter(ev, [t_last, t_last + period_us // 2], width=W, height=H, contrast_on_ln=c,
                           contrast_off_ln=c, cutoff_rad_s=alpha)
    q = math.exp(-alpha * period_us * 1e-6)
    peak = c / (1 - q)  # just after an event: geometric series of decayed steps
    assert out[0, 3, 4] == pytest.approx(peak, rel=1e-9)
    assert out[1, 3, 4] == pytest.approx(peak * math.exp(-alpha * period_us / 2 * 1e-6), rel=1e-9)


def test_high_pass_with_zero_cutoff_is_direct_integration():
    rng = np.random.default_rng(3)
    n = 500
    ev = np.zeros(n, BRIGHTNESS_DTYPE)
    ev["x"], ev["y"] = rng.integers(0, W, n), rng.integers(0, H, n)
    ev["t"], ev["p"] = np.sort(rng.integers(0, 10_000, n)), rng.random(n) < 0.5
    t = [2500, 5000, 10_000]
    np.testing.assert_allclose(
        high_pass_filter(ev, t, width=W, height=H, contrast_on_ln=0.2, contrast_off_ln=0.2, cutoff_rad_s=0.0),
        direct_integration(ev, t, width=W, height=H),
        atol=1e-12,
    )


@settings(max_examples=30, deadline=None)
@given(st.lists(st.tuples(st.integers(0, W - 1), st.integers(0, H - 1), st.integers(0, 10_000), st.booleans()),
                min_size=1, max_size=40))
def test_high_pass_on_off_symmetry(rows):
    rows = sorted(rows, key=lambda r: r[2])
    ev = events(rows)
    flipped = ev.copy()
    flipped["p"] = ~ev["p"]
    t = [5000, 10_001]
    a = high_pass_filter(ev, t, width=W, height=H, contrast_on_ln=0.2, contrast_off_ln=0.2, cutoff_rad_s=50.0)
    b = high_pass_filter(flipped, t, width=W, height=H, contrast_on_ln=0.2, contrast_off_ln=0.2, cutoff_rad_s=50.0)
    np.testing.assert_allclose(a, -b, atol=1e-12)


def test_complementary_filter_converges_to_the_frame_exponentially_without_events():
    alpha = 4.0
    frame = np.linspace(-1.0, 2.0, H * W).reshape(H, W)
    t = np.array([0, 100_000, 250_000, 1_000_000])
    out = complementary_filter(
        events([]), frame[None], [0], t, width=W, height=H, cutoff_rad_s=alpha, initial=np.zeros((H, W))
    )
    gain = 1 - np.exp(-alpha * t * 1e-6)
    np.testing.assert_allclose(out, gain[:, None, None] * frame[None], rtol=1e-12, atol=1e-15)


def test_complementary_filter_follows_a_new_frame_from_its_timestamp():
    alpha = 2.0
    f0, f1 = np.zeros((H, W)), np.full((H, W), 0.7)
    out = complementary_filter(
        events([]), np.stack([f0, f1]), [0, 300_000], [200_000, 300_000, 800_000], width=W, height=H, cutoff_rad_s=alpha
    )
    np.testing.assert_allclose(out[0], f0)  # default initial: the first frame
    np.testing.assert_allclose(out[1], f0)
    np.testing.assert_allclose(out[2], 0.7 * (1 - math.exp(-alpha * 0.5)), rtol=1e-12)


def test_complementary_filter_tracks_fast_changes_that_frames_miss():
    # True log signal: a 5-step staircase of ON events within 10 ms; APS frames at 0 and 50 ms.
    c = 0.2
    t_events = [2000, 4000, 6000, 8000, 10_000]
    ev = events([(1, 1, t, True) for t in t_events])
    frames = np.stack([np.zeros((H, W)), np.full((H, W), 1.0)])
    t_out = np.arange(1000, 12_000, 1000)
    truth = c * np.searchsorted(t_events, t_out, side="right")
    out = complementary_filter(ev, frames, [0, 50_000], t_out, width=W, height=H, contrast_on_ln=c, contrast_off_ln=c)
    alpha = COMPLEMENTARY_CUTOFF_RAD_S
    exact = [sum(c * math.exp(-alpha * (t - ti) * 1e-6) for ti in t_events if ti <= t) for t in t_out]
    np.testing.assert_allclose(out[:, 1, 1], exact, rtol=1e-12)
    # events pass at high frequency: the lag towards the stale frame is at most 1 - exp(-alpha * 10 ms)
    assert np.max(np.abs(out[:, 1, 1] - truth)) <= 1.0 * (1 - math.exp(-alpha * 0.01))
    assert np.max(np.abs(out[:, 1, 1] - truth)) < 0.02
    assert np.max(np.abs(0.0 - truth)) == pytest.approx(1.0)  # the frames alone miss the whole staircase


def test_reconstruction_of_millions_of_events_is_fast():
    rng = np.random.default_rng(0)
    n, w, h = 2_000_000, 346, 260
    ev = np.zeros(n, BRIGHTNESS_DTYPE)
    ev["x"], ev["y"] = rng.integers(0, w, n), rng.integers(0, h, n)
    ev["t"], ev["p"] = np.sort(rng.integers(0, 1_000_000, n)), rng.random(n) < 0.5
    t = np.arange(1, 11) * 100_000
    high_pass_filter(ev[:10], t, width=w, height=h)  # compile / load the cached kernel
    start = time.perf_counter()
    high_pass_filter(ev, t, width=w, height=h)
    assert time.perf_counter() - start < 1.0


@pytest.mark.parametrize("method", ["direct", "high_pass", "complementary"])
def test_inputs_are_validated(method):
    def call(ev, t_out=(10,), frames_t=(0,)):
        if method == "direct":
            return direct_integration(ev, t_out, width=W, height=H)
        if method == "high_pass":
            return high_pass_filter(ev, t_out, width=W, height=H)
        return complementary_filter(ev, np.zeros((len(frames_t), H, W)), frames_t, t_out, width=W, height=H)

    with pytest.raises(ValueError, match="sorted"):
        call(events([(0, 0, 5, True), (0, 0, 3, True)]))
    with pytest.raises(ValueError, match="outside the 5x4 sensor"):
        call(events([(W, 0, 1, True)]))
    with pytest.raises(ValueError, match="outside"):
        call(events([(0, -1, 1, True)]))
    with pytest.raises(ValueError, match="increase strictly"):
        call(events([]), t_out=(10, 10))
    with pytest.raises(ValueError, match="increase strictly"):
        call(events([]), t_out=(10, 5))
    with pytest.raises(TypeError, match="BRIGHTNESS_DTYPE"):
        call(np.zeros(3))
    if method == "complementary":
        with pytest.raises(ValueError, match="increase strictly"):
            call(events([]), frames_t=(5, 5))


def test_frame_stack_must_match_the_sensor_and_be_finite():
    with pytest.raises(ValueError, match="frames_log must have shape"):
        complementary_filter(events([]), np.zeros((1, H + 1, W)), [0], [1], width=W, height=H)
    bad = np.zeros((1, H, W))
    bad[0, 0, 0] = np.nan
    with pytest.raises(ValueError, match="finite"):
        complementary_filter(events([]), bad, [0], [1], width=W, height=H)
    with pytest.raises(ValueError, match="cutoff_rad_s"):
        high_pass_filter(events([]), [1], width=W, height=H, cutoff_rad_s=-1.0)
    with pytest.raises(ValueError, match="contrast_on_ln must be finite and > 0, got 0.0"):
        direct_integration(events([]), [1], width=W, height=H, contrast_on_ln=0.0)


@settings(max_examples=40, deadline=None)
@given(cuts=st.lists(st.integers(0, 3000), max_size=6, unique=True), seed=st.integers(0, 2**16))
def test_event_filter_fed_in_windows_equals_the_one_shot_filter(cuts, seed):
    """Cutting the events (and APS frames) into windows at any times changes no bit of the estimates."""
    rng = np.random.default_rng(seed)
    n = 400
    ev = np.zeros(n, BRIGHTNESS_DTYPE)
    ev["t"] = np.sort(rng.integers(0, 3000, n))
    ev["x"], ev["y"], ev["p"] = rng.integers(0, W, n), rng.integers(0, H, n), rng.random(n) < 0.5
    aps = rng.normal(0.0, 1.0, (3, H, W))
    aps_t = np.array([0, 900, 2100])
    out_t = np.array([500, 1500, 2999])
    one = complementary_filter(ev, aps, aps_t, out_t, width=W, height=H, cutoff_rad_s=300.0)
    filt = EventFilter(width=W, height=H, cutoff_rad_s=300.0, frames_log=aps, frames_t_us=aps_t, initial=aps[0],
                       t0_us=0)
    got, done = [], -1
    for until in sorted(set(cuts) | set(out_t.tolist())):
        filt.feed(ev[(ev["t"] > done) & (ev["t"] <= until)], until_us=until)
        done = until
        if until in out_t:
            got.append(filt.estimate(until))
    np.testing.assert_array_equal(np.asarray(got), one)


def test_event_filter_refuses_events_outside_the_window():
    filt = EventFilter(width=W, height=H, t0_us=0)
    filt.feed(events([(0, 0, 10, True)]), until_us=20)
    with pytest.raises(ValueError, match=r"fall outside the window \(20, 40\] us"):
        filt.feed(events([(0, 0, 20, True)]), until_us=40)
    with pytest.raises(ValueError, match="goes back"):
        filt.feed(events([]), until_us=10)
