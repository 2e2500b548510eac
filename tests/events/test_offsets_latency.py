"""Gradient comparator input offsets and the readout's latency floor and jitter (issue 23)."""

import math

import numpy as np
import pytest
from scipy.stats import norm

from gevsim.events import GradientEmulator
from gevsim.events.readout import JITTER_TRUNCATION, Readout
from gevsim.events.types import BRIGHTNESS_DTYPE
from gevsim.pixel.params import ReadoutParams


def test_comparator_offsets_give_the_gaussian_ternary_statistics():
    """A flat image: G = 0, so comparator (a, y, x) is +1 when -offset >= theta, -1 when -offset <= -theta.
    With offsets of sigma s, each state's share is Phi(-theta / s) (an offset moves +theta and -theta together)."""
    shape = (128, 128)
    theta, s = 0.05, 0.03
    em = GradientEmulator(shape, thresholds_ln=(theta,), offset_sigma_ln=s, rng=np.random.default_rng(0))
    state = em.ternary_of(np.zeros(shape))
    comparators = np.concatenate([state[0, :, :-1].ravel(), state[1, :-1, :].ravel()])  # the last column/row hold 0
    p = norm.cdf(-theta / s)
    n = comparators.size
    for value in (1, -1):
        share = np.mean(comparators == value)
        assert abs(share - p) < 4 * np.sqrt(p * (1 - p) / n), value
    # One comparator: it switches at G = offset + theta and G = offset - theta.
    o = em.offset[0, 5, 5]
    img = np.zeros(shape)
    for g, expected in ((o + theta + 1e-9, 1), (o + theta - 1e-9, 0), (o - theta - 1e-9, -1), (o - theta + 1e-9, 0)):
        img[5, 6] = g
        assert em.ternary_of(img)[0, 5, 5] == expected


def test_offsets_change_events_only_through_the_comparators():
    """The emulator's events are the ternary code of G - offset: decoding them from the initial state gives
    the offset comparators' final state."""
    rng = np.random.default_rng(1)
    shape = (16, 20)
    t = 1e-4 * np.arange(1, 201)
    v = np.cumsum(0.02 * rng.standard_normal((len(t),) + shape), axis=0).astype(np.float32)
    em = GradientEmulator(shape, thresholds_ln=(0.05, 0.1), offset_sigma_ln=0.04, rng=np.random.default_rng(2))
    ev = em.process(v, t)
    from gevsim.events.gradient import decode

    np.testing.assert_array_equal(decode(ev, em.initial_state), em.ternary_of(v[-1]))


def _requests(n, rate_eps, seed=0):
    rng = np.random.default_rng(seed)
    ev = np.zeros(n, BRIGHTNESS_DTYPE)
    ev["t"] = np.sort(rng.integers(0, int(n * 1e6 / rate_eps), n))
    ev["x"] = np.arange(n) % 300
    return ev


def test_latency_floor_delays_every_event_by_it():
    ev = _requests(1000, 1e5)
    out = Readout(ReadoutParams(latency_s=15e-6)).process(ev)
    np.testing.assert_array_equal(out["t"], ev["t"] + 15)
    np.testing.assert_array_equal(out["x"], ev["x"])


def test_jitter_is_a_truncated_normal_and_does_not_depend_on_chunks():
    ev = _requests(200_000, 1e6)
    params = ReadoutParams(latency_s=20e-6, latency_jitter_s=4e-6)
    whole = Readout(params, key=9).process(ev)
    assert np.all(np.diff(whole["t"]) >= 0)
    assert len(whole) == len(ev)
    r = Readout(params, key=9)
    parts = []
    bounds = [0, 50_000, 50_001, 120_000, len(ev)]
    for a, b in zip(bounds[:-1], bounds[1:]):
        last = b == len(ev)
        until = None if last else int(ev["t"][b])  # every later request comes at or after it
        parts.append(r.process(ev[a:b], until_us=until))
    chunked = np.concatenate(parts)
    np.testing.assert_array_equal(np.sort(chunked, order=["t", "x"]), np.sort(whole, order=["t", "x"]))
    # The delays of the events (matched through their unique request order): mean, sigma, bounds.
    delay = _delays(ev, whole)
    c = JITTER_TRUNCATION
    trunc_sd = np.sqrt(1 - 2 * c * norm.pdf(c) / (2 * norm.cdf(c) - 1))
    assert np.mean(delay) == pytest.approx(20.0 - 0.5, abs=0.1)  # floor() of the delayed time: -0.5 us on average
    assert np.std(delay) == pytest.approx(4.0 * trunc_sd, rel=0.03)
    assert delay.min() >= np.floor(20 - 3 * 4) - 1 and delay.max() <= 20 + 3 * 4


def _delays(requests, delivered):
    """Delivered minus requested time per event; events are told apart by a running id in x/y."""
    ids = np.arange(len(requests))
    req = requests.copy()
    req["x"], req["y"] = (ids % 30000).astype(np.int16), (ids // 30000).astype(np.int16)
    out = Readout(ReadoutParams(latency_s=20e-6, latency_jitter_s=4e-6), key=9).process(req)
    got = out["y"].astype(np.int64) * 30000 + out["x"]
    return out["t"] - req["t"][got]


def test_rate_controller_keeps_each_period_at_its_target_spread_evenly():
    """ERC: a period holding n > N = target x T events keeps N of them, evenly spread; quieter periods pass."""
    params = ReadoutParams(rate_controller_eps=1e6, rate_controller_period_s=200e-6)  # N = 200 per period
    ev = _requests(100_000, 4e6, seed=3)  # ~800 per period: 3/4 dropped
    ids = np.arange(len(ev))
    ev["x"], ev["y"] = (ids % 300).astype(np.int16), (ids // 300).astype(np.int16)  # an event's id
    quiet = _requests(50, 1e5, seed=4)
    quiet["y"] = -1
    quiet["t"] += int(ev["t"][-1]) + 1000
    ev = np.concatenate([ev, quiet])
    r = Readout(params)
    out = r.process(ev)
    per_period = np.bincount(out["t"] // 200)
    assert per_period.max() == 200
    assert r.summary()["rate_controller_dropped"] == len(ev) - len(out)
    assert np.all(np.isin(quiet["t"], out["t"]))  # the quiet tail is untouched
    busy = ev[ev["t"] // 200 == 10]
    kept = out[out["t"] // 200 == 10]
    assert len(kept) == 200
    idx = np.sort(kept["y"].astype(np.int64) * 300 + kept["x"])  # ids: evenly spread, gaps of n / N events, +-1
    gaps = np.diff(idx)
    assert gaps.min() >= len(busy) // 200 - 1 and gaps.max() <= len(busy) // 200 + 2
    # Chunk independence: the same events in three chunks.
    r2 = Readout(params)
    cuts = [0, 30_000, 30_001, len(ev)]
    parts = [r2.process(ev[a:b], until_us=None if b == len(ev) else int(ev["t"][b]))
             for a, b in zip(cuts[:-1], cuts[1:])]
    np.testing.assert_array_equal(np.concatenate(parts), out)


@pytest.mark.parametrize("target_eps, rate_eps, n, tolerance", [
    # IMX636's 200 keps on a 64x48 window: 0.13 per period; a few periods of a Poisson stream are idle.
    (200e3 * 64 * 48 / (1280 * 720), 5007 / 0.4, 5007, 0.03),
    (1.0025e6, 4e6, 200_000, 2e-5),  # 200.5 per period, every period busy: flooring lost 1 event in 400
])
def test_the_rate_controller_delivers_its_target_at_small_and_fractional_quotas(target_eps, rate_eps, n, tolerance):
    """Issue 36: flooring the quota of each 200 us period delivered 0 of 5,007 events at a 667 eps target; the
    token bucket carries the fraction, so a stream above the target delivers the target over its duration."""
    params = ReadoutParams(rate_controller_eps=target_eps, rate_controller_period_s=200e-6)
    ev = _requests(n, rate_eps, seed=5)
    out = Readout(params).process(ev)
    duration_s = (ev["t"][-1] // 200 + 1) * 200e-6  # whole periods
    expected = target_eps * duration_s
    # At 12.5 keps nearly every period is busy: the bucket is spent as it fills; at 4 Meps every period is.
    assert abs(len(out) - expected) <= max(1.0, tolerance * expected), (len(out), expected)
    per_period = np.bincount(out["t"] // 200)
    assert per_period.max() <= math.floor(target_eps * 200e-6) + 1  # never more than r + 1 in one period


def test_the_chip_share_scales_the_rate_controller_too():
    from gevsim.events.readout import chip_share

    share = chip_share(ReadoutParams(rate_controller_eps=1e8), emulated_px=100, chip_px=1000)
    assert share.rate_controller_eps == pytest.approx(1e7)
