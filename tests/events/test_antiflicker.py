"""The anti-flicker filter's documented behaviour: 4x4 blocks flickering at 50-500 Hz are silenced."""

import numpy as np
import pytest

from gevsim.events.antiflicker import AntiFlicker
from gevsim.events.readout import Readout
from gevsim.events.types import BRIGHTNESS_DTYPE
from gevsim.pixel.params import ReadoutParams


def _flicker(x, y, hz, n_cycles, t0_us=0, jitter_us=0, seed=0):
    """ON at the start of each period, OFF at its middle, at pixel (x, y)."""
    rng = np.random.default_rng(seed)
    period = 1e6 / hz
    t = t0_us + np.repeat(np.arange(n_cycles) * period, 2) + np.tile([0.0, period / 2], n_cycles)
    ev = np.zeros(len(t), BRIGHTNESS_DTYPE)
    ev["t"] = np.round(t + rng.integers(0, jitter_us + 1, len(t)))
    ev["x"], ev["y"] = x, y
    ev["p"] = np.tile([True, False], n_cycles)
    return ev


def _merge(*streams):
    ev = np.concatenate(streams)
    return ev[np.argsort(ev["t"], kind="stable")]


def test_a_block_flickering_in_band_is_silenced_after_its_cycles():
    params = ReadoutParams(anti_flicker=True, anti_flicker_cycles=4)
    lamp = _flicker(1, 1, 100.0, 20)  # 100 Hz in block (0, 0)
    slow = _flicker(9, 9, 30.0, 6)  # 30 Hz: a 33 ms period, outside 2-20 ms
    out = AntiFlicker((16, 16), params).process(_merge(lamp, slow))
    kept_lamp = out[(out["x"] == 1)]
    # A rise is an ON after an OFF: 10 ms (no period yet), then 20, 30, 40 and 50 ms build the streak of 4;
    # from the rise at 50 ms on, the block's events are dropped.
    assert kept_lamp["t"].max() < 50_000 and len(kept_lamp) == 10
    assert len(out[out["x"] == 9]) == len(slow)


def test_the_filter_lets_go_when_the_flicker_stops_and_ignores_aperiodic_blocks():
    f = AntiFlicker((16, 16), ReadoutParams(anti_flicker=True, anti_flicker_cycles=3))
    lamp = _flicker(2, 2, 200.0, 30)  # 150 ms of 200 Hz
    after = _flicker(2, 2, 7.0, 3, t0_us=400_000)  # then slow changes (a scene, not a lamp)
    rng = np.random.default_rng(1)
    noise = np.zeros(200, BRIGHTNESS_DTYPE)
    noise["t"] = np.sort(rng.integers(0, 600_000, 200))
    noise["x"], noise["y"], noise["p"] = 12, 12, rng.random(200) < 0.5
    out = f.process(_merge(lamp, after, noise))
    assert len(out[(out["x"] == 2) & (out["t"] >= 400_000)]) == len(after)
    assert len(out[out["x"] == 12]) >= 0.9 * 200  # random polarity changes rarely repeat a period 3 times
    assert f.dropped == len(lamp) + len(after) + 200 - len(out)


def test_same_events_in_any_chunks_and_through_the_readout():
    ev = _merge(_flicker(1, 1, 100.0, 30, jitter_us=300, seed=2), _flicker(5, 1, 333.0, 60, seed=3),
                _flicker(9, 5, 60.0, 12, seed=4))
    whole = AntiFlicker((8, 12), ReadoutParams(anti_flicker=True)).process(ev)
    f = AntiFlicker((8, 12), ReadoutParams(anti_flicker=True))
    parts = [f.process(ev[a:b]) for a, b in ((0, 17), (17, 18), (18, len(ev)))]
    np.testing.assert_array_equal(np.concatenate(parts), whole)
    r = Readout(ReadoutParams(anti_flicker=True), shape=(8, 12))
    np.testing.assert_array_equal(r.process(ev), whole)
    assert r.summary()["anti_flicker_dropped"] == len(ev) - len(whole) > 0
    with pytest.raises(ValueError, match="shape"):
        Readout(ReadoutParams(anti_flicker=True))
