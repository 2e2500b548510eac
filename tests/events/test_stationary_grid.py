"""The Gaussian row of gevsim.events.stationary: three exponentials for a whole grid of cells."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from gevsim.events.stationary import CELLS, _gauss_row


@settings(deadline=None)
@given(z0=st.floats(-60.0, 60.0), dz=st.floats(1e-7, 50.0), scale=st.floats(1e-3, 1e3))
def test_the_recurrence_is_a_gaussian_per_cell(z0, dz, scale):
    got = np.zeros(CELLS)
    _gauss_row(z0, dz, scale, got)
    exact = np.array([scale * math.exp(-0.5 * (z0 + k * dz) ** 2) for k in range(CELLS)])
    np.testing.assert_allclose(got, exact, rtol=1e-11, atol=1e-13 * max(exact.max(), 1e-300))
    assert (got >= 0.0).all() and np.isfinite(got).all()
    before = np.linspace(0.0, 1.0, CELLS)
    added = before.copy()
    _gauss_row(z0, dz, scale, added)  # it adds to what is there
    assert (added == before + got).all()


def test_a_row_far_from_its_peak_underflows_to_zero_not_to_nan():
    out = np.zeros(CELLS)
    _gauss_row(1e3, 1e9, 1.0, out)  # every cell ~1e3 sigma out, the step a billion sigma
    assert (out == 0.0).all()
    _gauss_row(-0.3, 1e9, 1.0, out)  # one cell near the peak, the rest gone
    assert out[0] == math.exp(-0.045) and (out[1:] == 0.0).all()
