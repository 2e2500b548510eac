"""The readout latency stage's compiled re-sort (gevsim.events._reorder) is numpy's stable sort, bit for bit."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from gevsim.events import _reorder
from gevsim.events.types import BRIGHTNESS_DTYPE, GRADIENT_DTYPE


@settings(deadline=None, max_examples=60)
@given(n=st.integers(0, 300), span=st.sampled_from([1, 7, 1000, 10**6, 10**12]), seed=st.integers(0, 2**32 - 1))
def test_the_order_is_numpys_stable_argsort(n, span, seed):
    """Counting sort over narrow spans (ties everywhere at span 1), merge sort over wide ones (10**6, 10**12)."""
    keys = np.random.default_rng(seed).integers(-5, span, n).astype(np.int64)
    assert (_reorder.stable_order(keys) == np.argsort(keys, kind="stable")).all()


@settings(deadline=None, max_examples=30)
@given(held=st.integers(0, 50), new=st.integers(0, 200), seed=st.integers(0, 2**32 - 1))
def test_held_and_delayed_events_merge_as_numpy_would(held, new, seed):
    """keys, order and every field as numpy's concatenate + floor + stable argsort + fancy index give them."""
    rng = np.random.default_rng(seed)
    for dtype in (BRIGHTNESS_DTYPE, GRADIENT_DTYPE):
        old = np.zeros(held, dtype)
        old["t"] = np.sort(rng.integers(100, 200, held))
        old["x"], old["y"] = rng.integers(0, 346, held), rng.integers(0, 260, held)
        events = np.zeros(new, dtype)
        events["t"] = np.sort(rng.integers(90, 300, new))
        events["x"], events["y"] = rng.integers(0, 346, new), rng.integers(0, 260, new)
        events["p"] = rng.integers(0, 2, new).astype(dtype["p"])
        delay = rng.uniform(0.0, 13.0, new)
        expected = events.copy()
        expected["t"] = np.floor(events["t"] + delay).astype(np.int64)
        expected = np.concatenate([old, expected])
        expected = expected[np.argsort(expected["t"], kind="stable")]
        keys = np.empty(held + new, np.int64)
        _reorder.delayed_keys(old["t"], events["t"], delay, keys)
        order = _reorder.stable_order(keys)
        got = np.empty(held + new, dtype)
        for name in dtype.names:
            if name == "t":
                _reorder.take(keys, keys[:0], order, got["t"])
            else:
                _reorder.take(old[name], events[name], order, got[name])
        assert got.tobytes() == expected.tobytes()
