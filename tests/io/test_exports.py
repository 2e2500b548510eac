"""`gevsim export` in every format, each read back with its client's own code and compared with the HDF5
stream (counts, fields, times)."""

from __future__ import annotations

import numpy as np
import pytest

from gevsim.cli import main
from gevsim.io import EventReader


def streams(path):
    with EventReader(path) as r:
        return {s: r.read(s) for s in r.streams}, r.width, r.height


def test_text_is_t_x_y_p_with_t_in_seconds_read_by_numpy_loadtxt(good, tmp_path, capsys):
    events, *_ = streams(good)
    out = tmp_path / "events.txt"
    assert main(["export", str(good), "--format", "text", "--out", str(out)]) == 0
    table = np.loadtxt(out, comments="#", ndmin=2)  # what ESIM/E2VID-style tooling does
    dvs = events["events"]
    assert table.shape == (len(dvs), 4)
    np.testing.assert_array_equal(np.rint(table[:, 0] * 1e6).astype(np.int64), dvs["t"])  # seconds, exact to 1 us
    np.testing.assert_array_equal(table[:, 1:3].astype(int), np.c_[dvs["x"], dvs["y"]])
    np.testing.assert_array_equal(table[:, 3].astype(int), (dvs["p"] > 0).astype(int))
    # A gradient stream carries its axis; only one stream fits a text file.
    assert main(["export", str(good), "--format", "text", "--stream", "gradient_events",
                 "--out", str(tmp_path / "g.txt")]) == 0
    g = np.loadtxt(tmp_path / "g.txt", comments="#", ndmin=2)
    np.testing.assert_array_equal(g[:, 4].astype(int), events["gradient_events"]["axis"])
    assert main(["export", str(good), "--format", "text", "--stream", "events,gradient_events",
                 "--out", str(tmp_path / "two.txt")]) == 2
    assert "one stream" in capsys.readouterr().err


def test_npz_holds_every_stream_with_tonics_fields(good, tmp_path):
    events, w, h = streams(good)
    out = tmp_path / "events.npz"
    assert main(["export", str(good), "--format", "npz", "--out", str(out)]) == 0
    with np.load(out) as z:
        assert (int(z["width"]), int(z["height"])) == (w, h)
        for name, ev in events.items():
            np.testing.assert_array_equal(z[name], ev)
            assert {"x", "y", "t", "p"} <= set(z[name].dtype.names)
    assert main(["export", str(good), "--format", "npz", "--out", str(out)]) == 0  # replaces its own export


def test_evreal_folder_is_read_by_evreals_layout(good, tmp_path):
    events, w, h = streams(good)
    out = tmp_path / "seq"
    assert main(["export", str(good), "--format", "evreal", "--out", str(out)]) == 0
    # EVREAL's loader (tools/.../dataset.py) reads these N x 1 / N x 2 arrays and metadata.json.
    ts, xy, p = (np.load(out / f"events_{n}.npy") for n in ("ts", "xy", "p"))
    dvs = events["events"]
    assert len(ts) == len(dvs)
    np.testing.assert_allclose(ts.ravel(), dvs["t"] / 1e6)
    np.testing.assert_array_equal(xy, np.c_[dvs["x"], dvs["y"]])
    images = np.load(out / "images.npy")
    assert images.dtype == np.uint8 and images.shape[1:3] == (h, w)
    # What EVREAL's MemMapDataset.load_data then does (numpy only; the class needs torch, which is not
    # installed): frame stamps one per image, image_event_indices (M, 1) read as [k][0], frames read as
    # images[k][:, :, 0], polarity as p * 2 - 1, the resolution from metadata.json as [H, W].
    import json

    stamps, indices = np.load(out / "images_ts.npy"), np.load(out / "image_event_indices.npy")
    assert len(stamps) == len(images) == len(indices) and indices.shape[1] == 1
    assert np.all(np.diff(indices[:, 0]) >= 0) and 0 <= indices.min() and indices.max() < len(ts)
    assert images[0][:, :, 0].shape == (h, w)
    np.testing.assert_array_equal(p.squeeze() * 2.0 - 1.0, np.where(dvs["p"] > 0, 1.0, -1.0))
    assert json.loads((out / "metadata.json").read_text())["sensor_resolution"] == [h, w]


def test_an_output_that_is_not_a_gevsim_export_is_refused(good, tmp_path, capsys):
    mine = tmp_path / "notes.txt"
    mine.write_text("my notes\n")
    assert main(["export", str(good), "--format", "text", "--out", str(mine)]) == 2
    assert mine.read_text() == "my notes\n"
    folder = tmp_path / "photos"
    folder.mkdir()
    (folder / "a.jpg").write_bytes(b"x")
    assert main(["export", str(good), "--format", "evreal", "--out", str(folder)]) == 2
    assert (folder / "a.jpg").exists()
    assert "not a gevsim" in capsys.readouterr().err


def test_the_text_export_round_trips_through_gevsims_reader(good, tmp_path):
    from gevsim.io.text import export_text, import_text

    events, *_ = streams(good)
    for name, ev in events.items():
        export_text(tmp_path / f"{name}.txt", ev, seconds=True)
        back = import_text(tmp_path / f"{name}.txt")
        for field in ("t", "x", "y"):
            np.testing.assert_array_equal(back[field], ev[field])


@pytest.mark.parametrize("fmt", ["text", "npz"])
def test_an_unknown_stream_is_named(good, tmp_path, capsys, fmt):
    assert main(["export", str(good), "--format", fmt, "--stream", "evnts", "--out", str(tmp_path / "x")]) == 2
    assert "no stream 'evnts'" in capsys.readouterr().err


def _read_like_e2vid(path):
    """A text event file read as E2VID reads it (github.com/uzh-rpg/rpg_e2vid, restated, not copied):
    ``run_reconstruction.py`` takes the sensor size from the first line (``pd.read_csv(..., header=None,
    names=['width', 'height'], nrows=1)``: two integers); ``utils/event_readers.py``'s
    ``FixedDurationEventReader`` skips that line and splits every other one with ``line.split(' ')`` into
    ``t, x, y, pol`` (float, int, int, int); ``utils/inference_utils.py``'s ``events_to_voxel_grid`` takes the
    rows ``[t, x, y, pol]``, turns pol 0 into -1 and indexes its grid with ``x + y * width``."""
    with open(path) as fh:
        width, height = (int(v) for v in fh.readline().split())  # ValueError unless exactly two integers
        rows = []
        for line in fh:
            t, x, y, pol = line.split(" ")
            rows.append([float(t), int(x), int(y), int(pol)])
    return width, height, np.array(rows, np.float64).reshape(-1, 4)


def test_the_e2vid_header_is_the_sensor_size_where_e2vids_reader_takes_it(good, tmp_path, capsys):
    events, w, h = streams(good)
    out = tmp_path / "events.txt"
    assert main(["export", str(good), "--format", "text", "--out", str(tmp_path / "plain.txt")]) == 0
    with pytest.raises(ValueError):  # the issue: gevsim's '#' line is not E2VID's 'W H'
        _read_like_e2vid(tmp_path / "plain.txt")
    assert main(["export", str(good), "--format", "text", "--header", "e2vid", "--out", str(out)]) == 0
    width, height, rows = _read_like_e2vid(out)
    dvs = events["events"]
    assert (width, height) == (w, h) and rows.shape == (len(dvs), 4)
    np.testing.assert_array_equal(np.rint(rows[:, 0] * 1e6).astype(np.int64), dvs["t"])  # seconds, exact to 1 us
    np.testing.assert_array_equal(rows[:, 1:3], np.c_[dvs["x"], dvs["y"]])
    np.testing.assert_array_equal(rows[:, 3], dvs["p"].astype(int))  # pol 1 = ON, 0 = OFF (E2VID makes it -1)
    index = rows[:, 1].astype(int) + rows[:, 2].astype(int) * width  # E2VID's voxel-grid index: in the grid
    assert index.min() >= 0 and index.max() < width * height
    # E2VID's FixedSizeEventReader (pandas, skiprows=1, whitespace-separated) reads the same table.
    np.testing.assert_array_equal(np.loadtxt(out, skiprows=1, ndmin=2), rows)
    from gevsim.io.text import import_text

    np.testing.assert_array_equal(import_text(out), dvs)  # gevsim reads it back too
    # A file with no gevsim mark is never replaced; E2VID reads brightness events only; text only.
    before = out.read_bytes()
    capsys.readouterr()
    assert main(["export", str(good), "--format", "text", "--header", "e2vid", "--out", str(out)]) == 2
    assert out.read_bytes() == before and "exists and is not a gevsim text export" in capsys.readouterr().err
    for argv, text in ((["--format", "text", "--header", "e2vid", "--stream", "gradient_events"], "gradient stream"),
                       (["--format", "npz", "--header", "e2vid"], "--header: applies to --format text only")):
        assert main(["export", str(good), *argv, "--out", str(tmp_path / "x")]) == 2
        err = capsys.readouterr().err.splitlines()
        assert len(err) == 1 and err[0].startswith("gevsim: error: ") and text in err[0]
        assert not (tmp_path / "x").exists()
