"""EVREAL sequence folders: layout EVREAL's MemMapDataset reads, round trip, errors."""

import json
import os

import numpy as np
import pytest

from gevsim.errors import ConfigError
from gevsim.events.types import BRIGHTNESS_DTYPE
from gevsim.io.evreal import TooFewEventsError, export_evreal, import_evreal

W, H = 32, 24


def make_events(n, rng, t_max=100_000):
    ev = np.zeros(n, dtype=BRIGHTNESS_DTYPE)
    ev["t"] = np.sort(rng.integers(0, t_max, n))
    ev["x"], ev["y"], ev["p"] = rng.integers(0, W, n), rng.integers(0, H, n), rng.random(n) < 0.5
    return ev


@pytest.fixture
def sequence(tmp_path, rng):
    ev = make_events(5000, rng)
    images = rng.integers(0, 256, (6, H, W), dtype=np.uint8)
    images_t = np.array([0, 20_000, 40_000, int(ev["t"][2500]), 80_000, 100_000])
    folder = tmp_path / "seq"
    export_evreal(folder, ev, images, images_t, width=W, height=H, extra_metadata={"scene": "panel"})
    return folder, ev, images, images_t


def test_round_trip(sequence):
    folder, ev, images, images_t = sequence
    ev2, images2, images_t2, width, height = import_evreal(folder)
    np.testing.assert_array_equal(ev2, ev)
    np.testing.assert_array_equal(images2, images)
    np.testing.assert_array_equal(images_t2, images_t)
    assert (width, height) == (W, H)


def test_file_shapes_and_dtypes(sequence):
    folder, ev, images, _ = sequence
    n, m = len(ev), len(images)
    expected = {"events_ts.npy": ((n,), np.float64), "events_xy.npy": ((n, 2), np.int16),
                "events_p.npy": ((n,), np.uint8), "images.npy": ((m, H, W, 1), np.uint8),
                "images_ts.npy": ((m, 1), np.float64), "image_event_indices.npy": ((m, 1), np.int64)}
    for name, (shape, dtype) in expected.items():
        arr = np.load(folder / name)
        assert (arr.shape, arr.dtype) == (shape, dtype), name
    assert set(np.unique(np.load(folder / "events_p.npy"))) == {0, 1}
    meta = json.loads((folder / "metadata.json").read_text())
    assert meta["sensor_resolution"] == [H, W] and meta["scene"] == "panel"
    assert sorted(os.listdir(folder.parent)) == ["seq"]


def test_image_event_indices_are_last_event_at_or_before_image(sequence):
    folder, ev, _, images_t = sequence
    idx = np.load(folder / "image_event_indices.npy")[:, 0]
    ts = np.load(folder / "events_ts.npy")
    for i, t_us in enumerate(images_t):
        at_or_before = np.flatnonzero(ev["t"] <= t_us)
        assert idx[i] == (at_or_before[-1] if len(at_or_before) else 0)
        if idx[i] + 1 < len(ts):
            assert ts[idx[i] + 1] > t_us / 1e6
    # EVREAL's own converter (tools/bag_to_npy.py) computes it from the seconds files
    img_ts = np.load(folder / "images_ts.npy")
    np.testing.assert_array_equal(idx, np.clip(np.searchsorted(ts, img_ts, "right") - 1, 0, len(ts) - 1)[:, 0])


def test_evreal_reader_arithmetic(sequence):
    """What MemMapDataset.get_frame / get_events compute gives back our data."""
    folder, ev, images, _ = sequence
    frames = np.load(folder / "images.npy", mmap_mode="r")
    np.testing.assert_array_equal(frames[3][:, :, 0], images[3])
    ps = np.load(folder / "events_p.npy") * 2.0 - 1.0
    np.testing.assert_array_equal(ps, np.where(ev["p"], 1.0, -1.0))
    xy = np.load(folder / "events_xy.npy")
    np.testing.assert_array_equal(xy[:, 0], ev["x"])
    np.testing.assert_array_equal(xy[:, 1], ev["y"])


def test_float_images_are_quantised(tmp_path, rng):
    ev = make_events(10, rng)
    images = np.array([np.full((H, W), 0.5), np.full((H, W), 1.7)])
    export_evreal(tmp_path / "f", ev, images, [0, 1000], width=W, height=H)
    _, images2, _, _, _ = import_evreal(tmp_path / "f")
    assert images2.dtype == np.uint8 and images2[0, 0, 0] == 128 and images2[1, 0, 0] == 255


def test_without_images(tmp_path, rng):
    ev = make_events(10, rng)
    export_evreal(tmp_path / "s", ev, None, None, width=W, height=H)
    assert sorted(os.listdir(tmp_path / "s")) == ["events_p.npy", "events_ts.npy", "events_xy.npy", "metadata.json"]
    ev2, images, images_t, _, _ = import_evreal(tmp_path / "s")
    np.testing.assert_array_equal(ev2, ev)
    assert images is None and images_t is None


def test_failed_export_leaves_existing_folder(sequence, rng):
    folder, ev, images, images_t = sequence
    before = {p: (folder / p).read_bytes() for p in os.listdir(folder)}
    with pytest.raises(ValueError, match=r"images must be \(M, 24, 32\)"):
        export_evreal(folder, ev, images[:, :10], images_t, width=W, height=H)
    assert {p: (folder / p).read_bytes() for p in os.listdir(folder)} == before
    assert os.listdir(folder.parent) == ["seq"]


def test_export_replaces_existing_folder(sequence, rng):
    folder, *_ = sequence
    ev = make_events(7, rng)
    export_evreal(folder, ev, None, None, width=W, height=H)
    assert not (folder / "images.npy").exists()
    np.testing.assert_array_equal(import_evreal(folder)[0], ev)
    assert os.listdir(folder.parent) == ["seq"]


def test_export_rejects_out_of_sensor_events(tmp_path, rng):
    ev = make_events(5, rng)
    ev["x"][2] = W
    with pytest.raises(ValueError, match="32x24"):
        export_evreal(tmp_path / "o", ev, None, None, width=W, height=H)
    assert os.listdir(tmp_path) == []


@pytest.mark.parametrize("name,bad,match", [
    ("events_p.npy", None, "events_p.npy: missing file"),
    ("events_xy.npy", np.zeros((3, 2), np.int16), r"events_xy.npy: must have shape \(5000, 2\)"),
    ("events_p.npy", np.zeros(4999, np.uint8), r"events_p.npy: polarities must have shape \(5000,\)"),
    ("images_ts.npy", np.zeros((5, 1)), r"images_ts.npy: image times must have shape \(6,\)"),
    ("image_event_indices.npy", np.full((6, 1), 5000), "image_event_indices.npy: indices"),
    ("images.npy", np.zeros((6, H, W + 1, 1), np.uint8), "images.npy: must be uint8"),
    ("events_ts.npy", b"garbage", "events_ts.npy: not a readable"),
    ("metadata.json", b"{}", "metadata.json: needs 'sensor_resolution'"),
    ("images.npy", None, "images.npy: missing file"),
])
def test_import_errors_name_the_file(sequence, name, bad, match):
    folder = sequence[0]
    path = folder / name
    if bad is None:
        path.unlink()
    elif isinstance(bad, bytes):
        path.write_bytes(bad)
    else:
        np.save(path, bad)
    with pytest.raises(ConfigError, match=match):
        import_evreal(folder)


def evreal_time_span(folder):
    """The first step of EVREAL's MemMapDataset.load_data (github.com/ercanburak/EVREAL, dataset.py):
    the sequence's time span is the first and last entry of events_ts.npy, squeezed."""
    t = np.load(folder / "events_ts.npy", mmap_mode="r").squeeze()
    return t[0], t[-1]


@pytest.mark.parametrize("n", [0, 1])
def test_no_folder_with_fewer_events_than_evreal_can_load(tmp_path, rng, n):
    images = rng.integers(0, 256, (2, H, W), dtype=np.uint8)
    few = make_events(n, rng)
    np.save(tmp_path / "events_ts.npy", few["t"] / 1e6)  # what gevsim used to write
    with pytest.raises(IndexError):
        evreal_time_span(tmp_path)
    with pytest.raises(TooFewEventsError, match=rf"few: not written: {n} events?, and EVREAL cannot load a "
                                                r"sequence with fewer than 2"):
        export_evreal(tmp_path / "few", few, images, [0, 1000], width=W, height=H)
    assert sorted(os.listdir(tmp_path)) == ["events_ts.npy"]  # nothing written
    two = make_events(2, rng)
    export_evreal(tmp_path / "two", two, images, [0, 1000], width=W, height=H)
    assert evreal_time_span(tmp_path / "two") == (two["t"][0] / 1e6, two["t"][1] / 1e6)
