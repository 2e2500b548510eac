"""Plots draw the model's own waveforms: a PWM's edges are vertical steps, not slopes between samples."""

from __future__ import annotations

import numpy as np

from gevsim.illumination import from_spec
from gevsim.plots import waveform_samples


def test_a_pwm_is_drawn_with_its_edges_and_only_its_two_levels():
    wf = from_spec({"type": "pwm", "frequency_hz": 500.0, "duty": 0.3})
    t, w = waveform_samples(wf, 0.01)
    levels = np.unique(np.round(w, 9))
    assert len(levels) == 2  # every drawn point is on or off: no point half way up an edge
    edges = wf.breakpoints_s(0.0, 0.01)
    assert len(edges) == 9  # 5 periods: on at 0 (the start), off at 0.6 ms, on at 2 ms, ...
    for e in edges[(edges > 0) & (edges < 0.01)]:
        before, after = w[np.searchsorted(t, e) - 1], w[np.searchsorted(t, e, side="right")]
        assert abs(t[np.searchsorted(t, e) - 1] - e) < 1e-9 and before != after  # a vertical step at e
