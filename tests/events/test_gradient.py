"""Gradient events: the paper's definitions, lossless code, RC, flicker immunity, chunking."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from gevsim.events import (
    BrightnessEmulator,
    GradientEmulator,
    decode,
    encode,
    gradients,
    ternary,
    threshold_matrix,
)
from gevsim.events._kernels import EVENT_TABLE
from gevsim.pixel import EventParams


def test_paper_table_and_threshold_matrix():
    # Lehtonen et al., Table 1: rows T_prev = -1, 0, 1; columns T = -1, 0, 1.
    assert EVENT_TABLE.tolist() == [[0, -1, 1], [-1, 0, 1], [-1, 1, 0]]
    theta = threshold_matrix((3, 4), (4 / 255, 8 / 255, 16 / 255))
    # Upper-left corner as printed in the paper: t0 t1 t2 t0 / t1 t2 t0 t1 / t2 t0 t1 t2.
    idx = np.rint(np.log2(theta * 255 / 4)).astype(int)
    assert idx.tolist() == [[0, 1, 2, 0], [1, 2, 0, 1], [2, 0, 1, 2]]


def test_each_table_row_is_a_permutation_so_the_code_is_lossless():
    for t_prev in (-1, 0, 1):
        row = [int(encode(np.array(t_prev), np.array(t))) for t in (-1, 0, 1)]
        assert sorted(row) == [-1, 0, 1] and row[t_prev + 1] == 0


def test_gradients_and_ternary_follow_the_definitions():
    img = np.array([[0.0, 0.1, 0.1, 0.5], [0.2, 0.2, 0.0, 0.5]])
    gx, gy = gradients(img)
    np.testing.assert_allclose(gx, [[0.1, 0.0, 0.4, 0.0], [0.0, -0.2, 0.5, 0.0]])
    np.testing.assert_allclose(gy, [[0.2, 0.1, -0.1, 0.0], [0.0, 0.0, 0.0, 0.0]])
    theta = np.full(img.shape, 0.1)
    assert ternary(gx, theta).tolist() == [[1, 0, 1, 0], [0, -1, 1, 0]]  # |G| >= theta counts


def test_resolution_compression_averages_pairs():
    img = np.arange(16.0).reshape(4, 4) ** 2
    gx, gy = gradients(img)
    rx, ry = gradients(img, rc=True)
    np.testing.assert_allclose(rx[:, 0], 0.5 * (gx[:, 0] + gx[:, 1]))
    np.testing.assert_allclose(rx[:, 1], rx[:, 0])
    np.testing.assert_allclose(rx[:, 2], 0.5 * (gx[:, 2] + gx[:, 3]))  # G_X of the last column is 0
    np.testing.assert_allclose(ry[0], 0.5 * (gy[0] + gy[1]))
    np.testing.assert_allclose(ry[3], ry[2])


@settings(max_examples=40, deadline=None)
@given(arrays(np.float64, (5, 6, 8), elements=st.floats(0, 1)), st.booleans(), st.booleans())
def test_decoding_the_events_recovers_the_ternary_state(frames, rc, interpolate):
    """Lossless: initial state + events give the ternary gradients of every frame."""
    em = GradientEmulator((6, 8), thresholds_ln=(4 / 255, 8 / 255, 16 / 255), rc=rc, interpolate=interpolate)
    t_s = 0.01 * np.arange(5)
    events = [em.process(frames[k:k + 1], t_s[k:k + 1]) for k in range(5)]
    state = em.initial_state
    for k in range(1, 5):
        state = decode(events[k], state)
        assert np.array_equal(state, em.ternary_of(frames[k]))
    everything = np.concatenate(events)
    assert np.array_equal(decode(everything, em.initial_state, t_us=int(t_s[2] * 1e6)), em.ternary_of(frames[2]))


def test_frame_mode_events_equal_the_table_applied_to_consecutive_frames():
    rng = np.random.default_rng(0)
    frames = rng.random((2, 10, 12))
    em = GradientEmulator((10, 12), thresholds_ln=(4 / 255, 8 / 255, 16 / 255), interpolate=False)
    em.process(frames[:1], [0.0])
    ev = em.process(frames[1:], [0.04])
    expected = encode(em.ternary_of(frames[0]), em.ternary_of(frames[1]))
    dense = np.zeros_like(expected)
    dense[ev["axis"], ev["y"], ev["x"]] = ev["p"]
    assert np.array_equal(dense, expected) and np.all(ev["t"] == 40000)


def test_global_flicker_gives_no_gradient_events_but_many_dvs_events():
    """A uniform multiplicative flicker adds the same ln offset to every pixel: gradients
    of the log image do not change (ideal pixel), brightness events fire everywhere."""
    rng = np.random.default_rng(1)
    scene = np.log(0.05 + rng.random((24, 32)))
    t = np.arange(400) * 50e-6
    flicker = np.log(1 + 0.9 * np.sin(2 * np.pi * 100 * t))  # 100 Hz, 90 % modulation
    v = scene[None] + flicker[:, None, None]
    grad = GradientEmulator((24, 32)).process(v, t)
    dvs = BrightnessEmulator((24, 32), EventParams(), rng=rng).process(v, t)
    assert len(grad) == 0
    assert len(dvs) > 24 * 32 * 2 * 5  # several events per pixel per flicker period


def test_interpolated_timestamp_of_a_ramp():
    # G_X grows linearly from 0 to 0.2 over 1 ms; threshold 0.05 at (0, 0): crossing at 250 us.
    v = np.zeros((2, 2, 2))
    v[1, :, 1] = 0.2
    em = GradientEmulator((2, 2), thresholds_ln=(0.05,))
    ev = em.process(v, [0.0, 1e-3])
    x_events = ev[ev["axis"] == 0]
    assert len(x_events) == 2 and np.all(x_events["t"] == 250) and np.all(x_events["p"] == 1)


def test_chunked_equals_one_shot_bit_for_bit():
    rng = np.random.default_rng(4)
    v = np.cumsum(rng.normal(0, 0.03, (90, 20, 22)), axis=0)
    t = np.cumsum(rng.uniform(1e-6, 3e-6, 90))
    for rc in (False, True):
        kw = dict(rc=rc, mismatch_sigma_ln=0.01)
        one = GradientEmulator((20, 22), rng=np.random.default_rng(5), **kw).process(v, t)
        em = GradientEmulator((20, 22), rng=np.random.default_rng(5), **kw)
        cuts = [0, 1, 30, 31, 89, 90]
        parts = np.concatenate([em.process(v[a:b], t[a:b]) for a, b in zip(cuts, cuts[1:])])
        assert len(one) > 500
        np.testing.assert_array_equal(one, parts)


def test_negating_the_input_negates_gradient_events():
    rng = np.random.default_rng(2)
    v = np.cumsum(rng.normal(0, 0.05, (30, 8, 9)), axis=0)
    t = 1e-4 * np.arange(30)
    a = GradientEmulator((8, 9)).process(v, t)
    b = GradientEmulator((8, 9)).process(-v, t)
    np.testing.assert_array_equal(a[["x", "y", "t", "axis"]], b[["x", "y", "t", "axis"]])
    np.testing.assert_array_equal(a["p"], -b["p"])


def test_rc_comparators_sit_at_even_positions():
    rng = np.random.default_rng(3)
    v = np.cumsum(rng.normal(0, 0.05, (40, 8, 10)), axis=0)
    ev = GradientEmulator((8, 10), rc=True).process(v, 1e-4 * np.arange(40))
    assert np.all(ev["x"][ev["axis"] == 0] % 2 == 0) and np.all(ev["y"][ev["axis"] == 1] % 2 == 0)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(rc=True, shape=(5, 6)), "even height and width"),
        (dict(thresholds_ln=(0.1, -0.2)), "positive"),
        (dict(theta=np.ones((3, 3))), "shape"),
        (dict(mismatch_sigma_ln=0.1), "rng"),
    ],
)
def test_bad_configuration(kwargs, match):
    shape = kwargs.pop("shape", (4, 6))
    with pytest.raises((ValueError, TypeError), match=match):
        GradientEmulator(shape, **kwargs)


def test_bad_input():
    em = GradientEmulator((4, 6))
    with pytest.raises(ValueError, match="finite"):
        em.process(np.full((2, 4, 6), np.nan), [0.0, 1.0])
    with pytest.raises(ValueError, match=r"shape \(T, 4, 6\)"):
        em.process(np.zeros((2, 6, 4)), [0.0, 1.0])
    with pytest.raises(ValueError, match="increase strictly"):
        em.process(np.zeros((2, 4, 6)), [1.0, 1.0])


def test_hysteresis_suppresses_chatter_near_threshold():
    """G dithering around the threshold: without hysteresis every crossing is an event,
    with hysteresis larger than the dither only the first."""
    g = 0.1 + 0.01 * np.tile([1.0, -1.0], 20)  # G_X alternates 0.11 / 0.09 around theta = 0.1
    v = np.zeros((len(g), 1, 2))
    v[:, 0, 1] = g
    t = 1e-4 * np.arange(len(g))
    plain = GradientEmulator((1, 2), thresholds_ln=(0.1,)).process(v, t)
    hyst = GradientEmulator((1, 2), thresholds_ln=(0.1,), hysteresis_ln=0.02).process(v, t)
    assert len(plain) == len(g) - 1 and len(hyst) == 0  # the first sample already sets T = 1
    with pytest.raises(ValueError, match="hysteresis"):
        GradientEmulator((1, 2), thresholds_ln=(0.1,), hysteresis_ln=0.1)


@pytest.mark.parametrize("rc", [False, True])
def test_emulator_state_equals_the_numpy_definition_on_every_row(rc):
    """Including the last row and column (G = 0 there) and the last RC pair."""
    rng = np.random.default_rng(7)
    frames = rng.random((6, 6, 8))
    em = GradientEmulator((6, 8), thresholds_ln=(0.02, 0.05, 0.1), rc=rc)
    for k in range(6):
        em.process(frames[k:k + 1], [0.1 * k])
        assert np.array_equal(em.state, em.ternary_of(frames[k]))
