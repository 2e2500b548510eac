"""The AER arbiter (issue 34, item 3): a pixel holds one request until it is acknowledged, so under
overload the bus delivers its rate, at most one request per pixel is pending at the end, and a
request waits at most for every other requester once (a fair arbiter: pixels / rate)."""

from __future__ import annotations

import numpy as np
import pytest

from gevsim.events.arbiter import ARBITERS
from gevsim.events.readout import Readout, ReadoutParams
from gevsim.events.types import BRIGHTNESS_DTYPE, GRADIENT_DTYPE

H, W = 24, 32
CAP_EPS = 2e5
RUN_US = 200_000


def poisson_requests(rate_eps: float, *, seed: int, dtype=BRIGHTNESS_DTYPE) -> np.ndarray:
    """Crossings at ``rate_eps`` in all, uniformly over the pixels, for 0.2 s."""
    rng = np.random.default_rng(seed)
    n = rng.poisson(rate_eps * RUN_US * 1e-6)
    ev = np.zeros(n, dtype)
    ev["t"] = np.sort(rng.integers(0, RUN_US, n))
    ev["x"], ev["y"] = rng.integers(0, W, n), rng.integers(0, H, n)
    ev["p"] = rng.random(n) < 0.5
    if "axis" in ev.dtype.names:
        ev["axis"] = rng.integers(0, 2, n)
    return ev


def read(ev: np.ndarray, params: ReadoutParams, *, chunk_us: int = 10_000, hold_s: float = 0.0):
    r = Readout(params, shape=(H, W), hold_s=hold_s)
    edges = np.searchsorted(ev["t"], np.arange(0, RUN_US + chunk_us, chunk_us))
    parts = []
    for a, b, until in zip(edges[:-1], edges[1:], np.arange(chunk_us, RUN_US + chunk_us, chunk_us)):
        last = until >= RUN_US
        parts.append(r.process(ev[a:b], end_us=RUN_US, until_us=None if last else int(until)))
    return np.concatenate(parts), r.summary()


@pytest.mark.parametrize("arbitration", list(ARBITERS))
@pytest.mark.parametrize("dtype", [BRIGHTNESS_DTYPE, GRADIENT_DTYPE])
def test_three_times_overload_delivers_the_cap_one_request_per_pixel_bounded_delay(arbitration, dtype):
    ev = poisson_requests(3 * CAP_EPS, seed=1, dtype=dtype)
    out, s = read(ev, ReadoutParams(max_rate_eps=CAP_EPS, arbitration=arbitration))
    requesters = H * W * (2 if "axis" in dtype.names else 1)
    assert s["delivered"] == len(out) == pytest.approx(CAP_EPS * RUN_US * 1e-6, rel=0.05)
    assert s["pending_at_end"] <= requesters
    assert s["requested"] == len(ev) == s["delivered"] + s["unsent"] + s["dropped"] + s["pending_at_end"]
    # A fair arbiter serves every other requester once at the most before a waiting one (row_column: each
    # row's other columns, each after a round of the other rows): requesters bus slots, +1 us of flooring.
    assert s["max_delay_us"] <= requesters * 1e6 / CAP_EPS + 1
    assert np.all(np.diff(out["t"]) >= 0) and out["t"].max() <= RUN_US
    assert len(np.unique(out["t"])) == len(out) or CAP_EPS > 1e6  # one address per bus slot


@pytest.mark.parametrize("arbitration", list(ARBITERS))
def test_a_waiting_pixel_cannot_fire_again_and_is_held_after_its_acknowledge(arbitration):
    """Pixel (0, 0) crosses at 0, 1, 2 us and 60 us; pixels (5, x) keep the 1 Meps bus busy for 10 us first.
    Its first request is read once the bus frees (the two others while it waits are unsent); the
    pixel is then held in reset for 50 us, so the crossing at 60 us is sent only if it comes after."""
    busy = np.zeros(10, BRIGHTNESS_DTYPE)
    busy["y"], busy["x"] = 5, np.arange(10)
    mine = np.zeros(4, BRIGHTNESS_DTYPE)
    mine["t"] = [0, 1, 2, 60]
    ev = np.concatenate([busy, mine])
    ev = ev[np.argsort(ev["t"], kind="stable")]
    r = Readout(ReadoutParams(max_rate_eps=1e6, arbitration=arbitration), shape=(H, W), hold_s=50e-6)
    out = r.process(ev)
    ours = out[(out["x"] == 0) & (out["y"] == 0)]
    s = r.summary()
    assert s["unsent"] >= 2 and s["delivered"] == len(out) == 10 + len(ours)
    ack = ours["t"][0]
    assert len(ours) == (2 if 60 >= ack + 50 else 1)
    assert s["requested"] == s["delivered"] + s["unsent"]


def test_results_do_not_depend_on_the_chunks():
    ev = poisson_requests(3 * CAP_EPS, seed=2)
    params = ReadoutParams(max_rate_eps=CAP_EPS)
    a, sa = read(ev, params, chunk_us=7_000, hold_s=1e-4)
    b, sb = read(ev, params, chunk_us=50_000, hold_s=1e-4)
    np.testing.assert_array_equal(a, b)
    assert sa == sb


def test_row_burst_reads_a_row_in_column_order_and_rows_in_turn():
    """All pixels of rows 3 and 7 request at t = 0: row 3's columns are read left to right, then row 7's."""
    ev = np.zeros(2 * W, BRIGHTNESS_DTYPE)
    ev["y"] = np.repeat([3, 7], W)
    ev["x"] = np.tile(np.arange(W)[::-1], 2)
    out = Readout(ReadoutParams(max_rate_eps=1e6), shape=(H, W)).process(ev)
    np.testing.assert_array_equal(out["y"], np.repeat([3, 7], W))
    np.testing.assert_array_equal(out["x"], np.tile(np.arange(W), 2))
    np.testing.assert_array_equal(out["t"], np.arange(2 * W))


@pytest.mark.parametrize("arbitration", list(ARBITERS))
def test_the_bus_goes_on_after_an_unsent_crossing(arbitration):
    """Pixel (0, 0) is read at 0 us and held 50 us, so its crossing at 10 us is unsent; pixel (3, 3)'s request at
    20 us is then read at once. (A bus left with nothing pending after an unsent crossing stopped serving: the
    office 96x72 run delivered every event in its first millisecond.)"""
    ev = np.zeros(3, BRIGHTNESS_DTYPE)
    ev["t"] = [0, 10, 20]
    ev["x"][2] = ev["y"][2] = 3
    r = Readout(ReadoutParams(max_rate_eps=1e6, arbitration=arbitration), shape=(H, W), hold_s=50e-6)
    out = r.process(ev, end_us=1000)
    np.testing.assert_array_equal(out["t"], [0, 20])
    s = r.summary()
    assert (s["delivered"], s["unsent"], s["pending_at_end"]) == (2, 1, 0)
