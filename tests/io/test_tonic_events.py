"""tonic's own ToFrame and ToVoxelGrid on gevsim streams through to_tonic / sensor_size: exact
signed counts per stream, polarity and gradient axis (and what goes wrong without the helper)."""

import numpy as np
import pytest
import tonic.transforms as tt

from gevsim.emulation import emulate_frames
from gevsim.events.types import BRIGHTNESS_DTYPE, GRADIENT_DTYPE
from gevsim.io import to_tonic, tonic_sensor_size
from gevsim.io.tonic_events import GRADIENT_CHANNELS, TONIC_DTYPE, sensor_size

H, W, N = 12, 16, 6
WINDOW_US = 1000


@pytest.fixture(scope="module")
def streams():
    """Real emulator output: a bar moving right over a dimming background, one frame per ms; every
    stream holds both polarities (and both gradient axes and signs)."""
    y, x = np.mgrid[0:H, 0:W]
    frames = [np.clip(0.3 + 0.2 * np.sin(x / 3.0 + y / 4.0) + 0.5 * (np.abs(x - 2 - 2 * k) < 2), 0, 1) * (1 - 0.05 * k)
              for k in range(N + 1)]
    out = emulate_frames(np.asarray(frames), np.arange(N + 1) * WINDOW_US * 1e-6, rng=np.random.default_rng(0))
    for name, ev in out.items():
        assert len(np.unique(ev["p"])) == 2, name
    assert set(np.unique(out["gradient_events"]["axis"])) == {0, 1}
    return out


def channel(ev):
    """Expected tonic channel of gevsim events, from their own fields."""
    if ev.dtype == BRIGHTNESS_DTYPE:
        return ev["p"].astype(int)
    return 2 * ev["axis"].astype(int) + (ev["p"] > 0)


def counts(ev, n_channels, bins):
    """(bins, channels, H, W) event counts in windows [k WINDOW_US, (k + 1) WINDOW_US)."""
    out = np.zeros((bins, n_channels, H, W), int)
    np.add.at(out, (ev["t"] // WINDOW_US, channel(ev), ev["y"], ev["x"]), 1)
    return out


@pytest.mark.parametrize("name", ["events", "gradient_events", "gradient_rc_events"])
def test_to_frame_counts_every_stream_per_polarity_and_axis(streams, name):
    ev = streams[name]
    size = sensor_size(W, H, ev)
    assert size == (W, H, 2 if ev.dtype == BRIGHTNESS_DTYPE else 4)
    frames = tt.ToFrame(sensor_size=size, time_window=WINDOW_US, start_time=0, end_time=(N + 1) * WINDOW_US)(
        to_tonic(ev))
    np.testing.assert_array_equal(frames, counts(ev, size[2], N + 1))
    assert frames.sum() == len(ev)


def on_grid(ev):
    """The events with timestamps moved onto whole windows from the first event's, g0, for N
    windows, and a copy of the last one at g0 + N windows: ToVoxelGrid scales time from the first
    to the last event, so bin k is then window k (the event at the very end falls out of the grid)."""
    ev = ev.copy()
    ev["t"] = ev["t"] // WINDOW_US * WINDOW_US
    g0 = ev["t"][0]
    ev = ev[ev["t"] < g0 + N * WINDOW_US]
    last = ev[-1:].copy()
    last["t"] = g0 + N * WINDOW_US
    return np.concatenate([ev, last])


@pytest.mark.parametrize("name, axis", [("events", None), ("gradient_events", 0), ("gradient_events", 1),
                                        ("gradient_rc_events", 0), ("gradient_rc_events", 1)])
def test_to_voxel_grid_gives_signed_counts_per_stream_and_axis(streams, name, axis):
    ev = streams[name]
    ev = on_grid(ev if axis is None else ev[ev["axis"] == axis])
    tonic_events = to_tonic(ev) if axis is None else to_tonic(ev, axis=axis)
    grid = tt.ToVoxelGrid(sensor_size=sensor_size(W, H, ev, axis=axis), n_time_bins=N)(tonic_events)
    expected = np.zeros((N + 1, H, W))
    np.add.at(expected, ((ev["t"] - ev["t"][0]) // WINDOW_US, ev["y"], ev["x"]), np.where(ev["p"] > 0, 1, -1))
    assert grid.shape == (N, 1, H, W)
    np.testing.assert_array_equal(grid[:, 0], expected[:N])
    assert np.any(expected < 0) and np.any(expected > 0)


def test_without_the_helper_tonic_miscounts(streams):
    """What users hit: a bool p turns OFF into +1 in ToVoxelGrid; gradient p = -1 indexes the last
    channel, so ToFrame puts both signs (and both axes) into one channel."""
    ev = on_grid(streams["events"])
    raw = tt.ToVoxelGrid(sensor_size=(W, H, 2), n_time_bins=N)(ev.copy())
    fixed = tt.ToVoxelGrid(sensor_size=(W, H, 2), n_time_bins=N)(to_tonic(ev))
    assert raw.min() >= 0 and fixed.min() < 0
    grad = streams["gradient_events"]
    frames = tt.ToFrame(sensor_size=(W, H, 2), n_event_bins=1)(grad.copy())
    assert frames[0, 0].sum() == 0 and frames[0, 1].sum() == len(grad)


def test_to_tonic_layout_and_errors(streams):
    grad = streams["gradient_events"]
    out = to_tonic(grad)
    assert out.dtype == TONIC_DTYPE and len(out) == len(grad)
    names = [GRADIENT_CHANNELS[c] for c in out["p"]]
    assert names == [f"{'xy'[a]}{'+' if p > 0 else '-'}" for a, p in zip(grad["axis"], grad["p"])]
    np.testing.assert_array_equal(out["t"], grad["t"])
    assert len(to_tonic(grad, axis=1)) == int(np.count_nonzero(grad["axis"] == 1))
    assert tonic_sensor_size(W, H, GRADIENT_DTYPE, axis=0) == (W, H, 2)
    with pytest.raises(ValueError, match="gradient events only"):
        to_tonic(streams["events"], axis=0)
    with pytest.raises(ValueError, match="axis must be None"):
        to_tonic(grad, axis=2)
    with pytest.raises(TypeError, match="BRIGHTNESS_DTYPE or GRADIENT_DTYPE"):
        to_tonic(np.zeros(3, TONIC_DTYPE))
    with pytest.raises(TypeError, match="event array or its dtype"):
        sensor_size(W, H, [1, 2])


@pytest.mark.parametrize("name, axis", [("events", None), ("gradient_events", 0), ("gradient_events", 1)])
def test_random_flip_polarity_negates_a_brightness_or_one_axis_stream(streams, name, axis):
    """Issue 26: tonic's RandomFlipPolarity inverts p as a bool. On a brightness stream or one gradient
    axis (to_tonic(..., axis=...): ON = upward step) that is exactly negating every step."""
    ev = streams[name]
    tonic_events = to_tonic(ev, axis=axis)
    flipped = tt.RandomFlipPolarity(p=1.0)(tonic_events.copy())
    np.testing.assert_array_equal(flipped["p"], 1 - tonic_events["p"])
    np.testing.assert_array_equal(flipped[["x", "y", "t"]], tonic_events[["x", "y", "t"]])


def test_random_flip_polarity_breaks_the_four_channel_gradient_layout(streams):
    """...but on the 4-channel gradient layout (axis and sign in p) it sends every Y event to channel 0
    (X, downward): flip each axis' stream instead (documented in to_tonic)."""
    four = to_tonic(streams["gradient_events"])
    flipped = tt.RandomFlipPolarity(p=1.0)(four.copy())
    assert set(np.unique(flipped["p"][four["p"] >= 2])) == {0}
