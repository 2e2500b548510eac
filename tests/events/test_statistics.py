"""Event statistics: the paper's per-frame event probability and event rates."""

import numpy as np
import pytest

from gevsim.events.statistics import event_probability, event_rates
from gevsim.events.types import AXIS_X, AXIS_Y, BRIGHTNESS_DTYPE, GRADIENT_DTYPE


def _events(dtype, rows):
    ev = np.zeros(len(rows), dtype)
    for i, row in enumerate(rows):
        ev[i] = row
    return ev


FRAMES_US = np.array([100, 200, 300])  # intervals (100, 200] and (200, 300]


def test_brightness_probability_counts_each_pixel_once():
    # (x, y, t, p) on a 4x2 sensor (8 pixels).
    ev = _events(BRIGHTNESS_DTYPE, [
        (0, 0, 50, True),    # before the first frame: not counted
        (0, 0, 100, True),   # at the first frame time: belongs to no interval
        (1, 0, 150, True), (1, 0, 160, False), (1, 0, 200, True),  # one pixel, three events
        (2, 1, 200, False),  # t == frame time: belongs to the interval ending there
        (1, 0, 201, True),   # same pixel, next interval
        (3, 1, 300, True), (0, 1, 250, False),
        (3, 1, 301, True),   # after the last frame: not counted
    ])
    ev = np.sort(ev, order="t", kind="stable")
    p = event_probability(ev, FRAMES_US, width=4, height=2)
    np.testing.assert_array_equal(p, [2 / 8, 3 / 8])


def test_gradient_probability_counts_every_event_of_both_axes():
    # (x, y, t, p, axis): repeated events at one comparator all count.
    ev = _events(GRADIENT_DTYPE, [
        (0, 0, 100, 1, AXIS_X),
        (0, 0, 150, 1, AXIS_X), (0, 0, 150, 1, AXIS_Y), (0, 0, 200, -1, AXIS_X),
        (1, 1, 300, -1, AXIS_Y),
    ])
    p = event_probability(ev, FRAMES_US, width=4, height=2)
    np.testing.assert_array_equal(p, [3 / 8, 1 / 8])


def test_probability_of_no_events_and_float_frame_times():
    empty = np.zeros(0, BRIGHTNESS_DTYPE)
    np.testing.assert_array_equal(event_probability(empty, [0.0, 1e3, 2e3, 3e3], width=3, height=3), [0, 0, 0])
    ev = _events(BRIGHTNESS_DTYPE, [(2, 2, 1000, True)])
    np.testing.assert_array_equal(event_probability(ev, [0.0, 1e3], width=3, height=3), [1 / 9])


def test_probability_validates_input():
    ev = _events(BRIGHTNESS_DTYPE, [(0, 0, 150, True)])
    with pytest.raises(ValueError, match="increase strictly: frame 2"):
        event_probability(ev, [100, 200, 200], width=4, height=2)
    with pytest.raises(TypeError, match="BRIGHTNESS_DTYPE or GRADIENT_DTYPE"):
        event_probability(np.zeros(3), FRAMES_US, width=4, height=2)
    with pytest.raises(ValueError, match="outside the 1x2 sensor"):
        _ = event_probability(_events(BRIGHTNESS_DTYPE, [(1, 0, 150, True)]), FRAMES_US, width=1, height=2)
    with pytest.raises(ValueError, match="width must be a positive integer"):
        event_probability(ev, FRAMES_US, width=0, height=2)


def test_rates_per_polarity_and_axis():
    b = _events(BRIGHTNESS_DTYPE, [(0, 0, 1, True), (1, 0, 2, True), (0, 1, 3, True), (0, 0, 4, False)])
    assert event_rates(b, 2.0, width=2, height=2) == {"total": 2.0, "on": 1.5, "off": 0.5, "per_pixel_hz": 0.5}
    g = _events(GRADIENT_DTYPE, [(0, 0, 1, 1, AXIS_X), (0, 0, 2, -1, AXIS_Y), (0, 0, 3, -1, AXIS_Y),
                                 (0, 0, 4, -1, AXIS_Y), (0, 0, 5, 1, AXIS_Y)])
    assert event_rates(g, 0.5) == {"total": 10.0, "+1": 4.0, "-1": 6.0, "x": 2.0, "y": 8.0}
    with pytest.raises(ValueError, match="duration_s must be finite and > 0, got 0.0"):
        event_rates(g, 0.0)
    with pytest.raises(ValueError, match="both width and height"):
        event_rates(g, 1.0, width=4)
