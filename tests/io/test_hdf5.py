"""DSEC-like HDF5 event files: round trips, ms_to_idx, windows, atomicity, errors."""

import math
import os

import h5py
import hypothesis.extra.numpy as hnp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import gevsim
from gevsim.errors import ConfigError
from gevsim.events.types import BRIGHTNESS_DTYPE, GRADIENT_DTYPE
from gevsim.io.hdf5 import FORMAT, EventReader, EventWriter

META = dict(width=64, height=48, config_toml='[sensor]\nwidth = 64\n', seed=7)


def make_events(t, *, gradient=False, seed=0):
    rng = np.random.default_rng(seed)
    ev = np.zeros(len(t), dtype=GRADIENT_DTYPE if gradient else BRIGHTNESS_DTYPE)
    ev["t"] = np.sort(np.asarray(t, dtype=np.int64))
    ev["x"], ev["y"] = rng.integers(0, 64, len(t)), rng.integers(0, 48, len(t))
    if gradient:
        ev["p"], ev["axis"] = rng.choice([-1, 1], len(t)), rng.integers(0, 2, len(t))
    else:
        ev["p"] = rng.random(len(t)) < 0.5
    return ev


def brute_ms_to_idx(t, t_end_us):
    return np.array([np.searchsorted(t, k * 1000, side="left") for k in range(math.ceil(t_end_us / 1000) + 1)])


times = hnp.arrays(np.int64, st.integers(0, 300), elements=st.integers(0, 12_000))


@settings(max_examples=30, deadline=None)
@given(t=times, cuts=st.lists(st.integers(0, 300), max_size=4), extra_us=st.integers(0, 3000),
       compression=st.sampled_from(["gzip", "lzf"]))
def test_chunked_round_trip_and_ms_to_idx(tmp_path_factory, t, cuts, extra_us, compression):
    path = tmp_path_factory.mktemp("h5") / "ev.h5"
    ev = make_events(t)
    t_end = (int(ev["t"][-1]) if len(ev) else 0) + extra_us
    with EventWriter(path, compression=compression, **META) as w:
        for chunk in np.split(ev, sorted(c for c in cuts if c <= len(ev))):
            w.append("events", chunk)
        w.set_end(t_end)
    with EventReader(path) as r:
        np.testing.assert_array_equal(r.read("events"), ev)
        assert r.read("events").dtype == BRIGHTNESS_DTYPE
        np.testing.assert_array_equal(r.ms_to_idx("events"), brute_ms_to_idx(ev["t"], t_end))
        assert r.t_end_us == t_end


@pytest.fixture(scope="module")
def window_file(tmp_path_factory):
    rng = np.random.default_rng(3)
    # clustered on millisecond boundaries, with a gap from 9 to 14 ms
    t = np.concatenate([np.arange(0, 9000, 250), [999, 1000, 1000, 1001, 4000, 4000],
                        rng.integers(14_000, 30_000, 2000)])
    ev = make_events(t, seed=1)
    path = tmp_path_factory.mktemp("win") / "win.h5"
    with EventWriter(path, **META) as w:
        for chunk in np.array_split(ev, 7):
            w.append("events", chunk)
    return path, ev


@settings(max_examples=150, deadline=None)
@given(start=st.one_of(st.none(), st.integers(-2000, 33_000)), end=st.one_of(st.none(), st.integers(-2000, 33_000)))
def test_window_read_equals_mask(window_file, start, end):
    path, ev = window_file
    mask = np.ones(len(ev), bool)
    if start is not None:
        mask &= ev["t"] >= start
    if end is not None:
        mask &= ev["t"] < end
    with EventReader(path) as r:
        np.testing.assert_array_equal(r.read("events", start, end), ev[mask])


@settings(max_examples=100, deadline=None)
@given(start=st.integers(0, 33_000), length=st.integers(0, 33_000), max_events=st.integers(1, 400))
def test_windows_cover_the_range_and_hold_at_most_max_events(window_file, start, length, max_events):
    """Consecutive windows, together exactly [start, end); each within max_events, or one
    millisecond (inner boundaries are whole milliseconds), so memory is bounded."""
    path, ev = window_file
    end = start + length
    with EventReader(path) as r:
        windows = r.windows("events", start, end, max_events=max_events)
        if length == 0:
            assert windows == []
            return
        assert windows[0][0] == start and windows[-1][1] == end
        assert all(a < b and b == c for (a, b), (c, _) in zip(windows, windows[1:] + [(end, None)]))
        for a, b in windows:
            n = int(np.count_nonzero((ev["t"] >= a) & (ev["t"] < b)))
            assert n <= max_events or (b - 1) // 1000 == a // 1000, (a, b, n)
            assert a == start or a % 1000 == 0
        lo, hi = r.index_bounds("events", [start, end])
        exact = np.searchsorted(ev["t"], [start, end], side="left")
        assert np.all(lo <= exact) and np.all(exact <= hi)


def test_windows_reject_bad_bounds(window_file):
    with EventReader(window_file[0]) as r:
        with pytest.raises(ValueError, match="max_events"):
            r.windows("events", 0, 10, max_events=0)
        with pytest.raises(ValueError, match=">= 0 us"):
            r.windows("events", -5, 10)
        assert r.count("events") == len(window_file[1]) and r.first_t_us("events") == 0


@pytest.mark.parametrize("start,end,expected", [
    (1000, 1001, 3), (999, 1000, 1), (1000, 1000, 0), (4000, 4001, 3), (9500, 13_999, 0), (5000, 4000, 0),
    (40_000, 50_000, 0), (-500, 0, 0), (0, 1, 1)])
def test_window_edges(window_file, start, end, expected):
    path, ev = window_file
    with EventReader(path) as r:
        got = r.read("events", t_start_us=start, t_end_us=end)
    assert len(got) == expected
    assert np.all((got["t"] >= start) & (got["t"] < end))


def test_multiple_streams_frames_arrays_and_attrs(tmp_path, rng):
    path = tmp_path / "multi.h5"
    bright = make_events(rng.integers(0, 5000, 400))
    grad = make_events(rng.integers(0, 7200, 300), gradient=True, seed=2)
    cs = make_events(rng.integers(100, 900, 50), seed=3)
    img = rng.random((48, 64, 3)).astype(np.float32)
    thr = rng.normal(0.2, 0.01, (48, 64))
    with EventWriter(path, extra_attrs={"scene": "panel"}, **META) as w:
        for i in range(0, 400, 100):
            w.append("events", bright[i:i + 100])
        w.append("gradient_events", grad)
        w.append("csdvs_events", cs)
        w.append_frame("irradiance", img, 0)
        w.append_frame("irradiance", img * 2, 1000)
        w.write_array("thresholds/on", thr, attrs={"unit": "ln"})
        w.set_attrs("gradient_events", method="lehtonen")
    with EventReader(path) as r:
        assert r.streams == ("csdvs_events", "events", "gradient_events")
        np.testing.assert_array_equal(r.read("gradient_events"), grad)
        assert r.read("gradient_events").dtype == GRADIENT_DTYPE
        np.testing.assert_array_equal(r.read("csdvs_events"), cs)
        lengths = {len(r.ms_to_idx(s)) for s in r.streams}
        assert lengths == {math.ceil(int(grad["t"][-1]) / 1000) + 1}
        np.testing.assert_array_equal(r.ms_to_idx("csdvs_events"), brute_ms_to_idx(cs["t"], r.t_end_us))
        images, t_us = r.frames("irradiance")
        assert images.shape == (2, 48, 64, 3) and images.dtype == np.float32
        np.testing.assert_array_equal(images[1], img * 2)
        np.testing.assert_array_equal(t_us, [0, 1000])
        np.testing.assert_array_equal(r.array("thresholds/on"), thr)
        assert r.array_attrs("thresholds/on")["unit"] == "ln"
        assert (r.width, r.height, r.seed, r.config_toml) == (64, 48, 7, META["config_toml"])
        assert r.gevsim_version == gevsim.__version__
        assert r.attrs["scene"] == "panel" and r.attrs["format"] == FORMAT and r.attrs["complete"]
    with h5py.File(path) as f:
        assert f["gradient_events"].attrs["method"] == "lehtonen"
        assert f["events/t"].compression == "gzip" and f["events/t"].dtype == np.int64
        assert f["events/p"].dtype == np.uint8 and f["gradient_events/axis"].dtype == np.uint8
        np.testing.assert_array_equal(f["events/p"][()], bright["p"].astype(np.uint8))  # DSEC: 1 ON, 0 OFF
        assert f["ms_to_idx"] == f["events/ms_to_idx"] and f["t_offset"][()] == 0  # DSEC's root layout
        assert f["events/x"].attrs["units"] == "px" and "meaning" in f["gradient_events/p"].attrs


def test_explicit_end_pads_every_stream(tmp_path):
    path = tmp_path / "end.h5"
    ev = make_events([10, 1500, 2500])
    with EventWriter(path, **META) as w:
        w.append("events", ev)
        w.close(t_end_us=10_001)
    with EventReader(path) as r:
        np.testing.assert_array_equal(r.ms_to_idx(), [0, 1, 2, 3] + [3] * 8)


def test_exception_inside_with_leaves_no_file(tmp_path):
    path = tmp_path / "killed.h5"
    with pytest.raises(RuntimeError, match="boom"):
        with EventWriter(path, **META) as w:
            w.append("events", make_events(range(100)))
            raise RuntimeError("boom")
    assert os.listdir(tmp_path) == []


def test_exception_leaves_existing_file_untouched(tmp_path):
    path = tmp_path / "run.h5"
    path.write_bytes(b"previous result")
    with pytest.raises(RuntimeError):
        with EventWriter(path, **META) as w:
            w.append("events", make_events(range(10)))
            raise RuntimeError
    assert path.read_bytes() == b"previous result"
    assert os.listdir(tmp_path) == ["run.h5"]


def test_unfinished_writer_is_not_at_path(tmp_path):
    path = tmp_path / "open.h5"
    w = EventWriter(path, **META)
    w.append("events", make_events(range(10)))
    assert not path.exists()
    w.abort()
    assert os.listdir(tmp_path) == []


def test_non_monotonic_across_appends_names_stream(tmp_path):
    with pytest.raises(ValueError, match=r"'gradient_events'.*t=500 us.*t=900 us"):
        with EventWriter(tmp_path / "bad.h5", **META) as w:
            w.append("gradient_events", make_events([100, 900], gradient=True))
            w.append("gradient_events", make_events([500, 1000], gradient=True))
    assert os.listdir(tmp_path) == []


def test_non_monotonic_within_chunk_names_stream(tmp_path):
    ev = make_events([1, 2, 3])
    ev["t"] = [5, 9, 7]
    with EventWriter(tmp_path / "bad.h5", **META) as w:
        with pytest.raises(ValueError, match=r"'csdvs_events'.*t\[1\]=9 us.*t\[2\]=7 us"):
            w.append("csdvs_events", ev)


def test_dtype_must_match_stream(tmp_path):
    with EventWriter(tmp_path / "d.h5", **META) as w:
        w.append("other", make_events([1]))
        with pytest.raises(TypeError, match="'other'"):
            w.append("other", make_events([2], gradient=True))
        with pytest.raises(TypeError, match="'events'"):
            w.append("events", make_events([2], gradient=True))


def test_end_before_last_event_is_an_error(tmp_path):
    w = EventWriter(tmp_path / "e.h5", **META)
    w.append("events", make_events([5000]))
    with pytest.raises(ValueError, match="t_end_us=4000"):
        w.close(t_end_us=4000)
    assert os.listdir(tmp_path) == []


def test_reader_rejects_foreign_and_incomplete_files(tmp_path):
    text = tmp_path / "notes.h5"
    text.write_text("hello")
    with pytest.raises(ConfigError, match="notes.h5.*not an HDF5 file"):
        EventReader(text)
    foreign = tmp_path / "foreign.h5"
    with h5py.File(foreign, "w") as f:
        f["events/t"] = np.arange(3)
    with pytest.raises(ConfigError, match="foreign.h5.*not a gevsim event file"):
        EventReader(foreign)
    partial = tmp_path / "partial.h5"
    with h5py.File(partial, "w") as f:
        f.attrs["format"] = FORMAT
    with pytest.raises(ConfigError, match="partial.h5.*incomplete"):
        EventReader(partial)
    with pytest.raises(ConfigError, match="missing.h5"):
        EventReader(tmp_path / "missing.h5")


def test_unknown_stream_suggests_a_name(tmp_path):
    path = tmp_path / "s.h5"
    with EventWriter(path, **META) as w:
        w.append("events", make_events([1]))
    with EventReader(path) as r, pytest.raises(ConfigError, match="did you mean 'events'"):
        r.read("event")


def test_a_plain_h5py_handle_and_a_reader_are_open_at_once(good):
    """Issue 26: EventReader opened without HDF5 file locking, so h5py.File(path) (locking by default) in the
    same process failed with "file locking flag values don't match", whichever was opened first."""
    import h5py

    from gevsim.io import EventReader

    with h5py.File(good, "r") as f, EventReader(good) as r:
        assert len(r.read("events")) == f["events/t"].shape[0]
    with EventReader(good) as r, h5py.File(good, "r") as f:
        assert r.width == f.attrs["width"]
    with h5py.File(good, "r", locking=False) as f, EventReader(good) as r:  # and a handle without locking
        assert r.height == f.attrs["height"]


def test_a_handle_held_past_a_write_does_not_move_the_chunks(tmp_path):
    """Where a frame's or an array's chunks go in the file follows the writes alone. A dataset handle that
    outlives its write (a thread sampling the stack holds the frame that owns it, as Dask's profiler does)
    once kept the chunk in HDF5's cache until it was freed, and the file came out in another byte order
    (issue 37, ``benchmarks/layout_determinism.py``). Two files, with and without such handles, are equal."""
    def write(path, hold):
        held = []
        writer = EventWriter(path, width=8, height=6, config_toml="", seed=0)
        for k in range(4):
            writer.append_frame("depth", np.full((6, 8), k, np.float32), 10 * k + 1)
            if hold:
                held.append(writer._file["frames/depth/images"])
            writer.append_frame("flow", np.full((6, 8, 2), -k, np.float32), 10 * k + 1)
        writer.write_array("thresholds/on", np.linspace(0.1, 0.3, 48).reshape(6, 8))
        if hold:
            held.append(writer._file["thresholds/on"])
        writer.write_array("thresholds/off", np.linspace(0.2, 0.4, 48).reshape(6, 8))
        writer.close(40)
        return path.read_bytes()

    assert write(tmp_path / "held.h5", True) == write(tmp_path / "freed.h5", False)
