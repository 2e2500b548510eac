"""AEDAT4 export through dv-processing: every event of every stream survives a round trip."""

import numpy as np
import pytest

from gevsim.cli import main
from gevsim.errors import ConfigError
from gevsim.events.types import BRIGHTNESS_DTYPE, GRADIENT_DTYPE
from gevsim.io.hdf5 import EventWriter

pytest.importorskip("dv_processing", reason="AEDAT4 export needs the aedat4 extra (dv-processing)")
from gevsim.io.aedat4 import export_aedat4, read_aedat4  # noqa: E402

W, H = 40, 30


def events(n, dtype, seed):
    rng = np.random.default_rng(seed)
    ev = np.zeros(n, dtype)
    ev["t"] = np.sort(rng.integers(0, 120_000, n))  # over two of the exporter's 50 ms windows
    ev["x"], ev["y"] = rng.integers(0, W, n), rng.integers(0, H, n)
    if dtype == GRADIENT_DTYPE:
        ev["p"], ev["axis"] = rng.choice([-1, 1], n), rng.integers(0, 2, n)
    else:
        ev["p"] = rng.random(n) < 0.5
    return ev


def write_run(path, **streams):
    """An emulation file holding ``streams`` (name -> events), 120 ms long."""
    with EventWriter(path, width=W, height=H, config_toml="", seed=0) as w:
        for name, ev in streams.items():
            w.append(name, ev)
        w.close(t_end_us=120_000)
    return path


@pytest.fixture
def emulation(tmp_path):
    dvs, grad = events(5000, BRIGHTNESS_DTYPE, 1), events(7000, GRADIENT_DTYPE, 2)
    return write_run(tmp_path / "run.h5", events=dvs, gradient_events=grad), dvs, grad


def same(aedat, ev):
    assert np.array_equal(aedat["timestamp"], ev["t"])
    assert np.array_equal(aedat["x"], ev["x"]) and np.array_equal(aedat["y"], ev["y"])
    assert np.array_equal(aedat["polarity"].astype(bool), ev["p"] > 0)


def test_round_trip_of_brightness_and_both_gradient_axes(emulation, tmp_path):
    path, dvs, grad = emulation
    counts = export_aedat4(path, tmp_path / "run.aedat4")
    assert counts == {"events": 5000, "events_gradient_x": int((grad["axis"] == 0).sum()),
                      "events_gradient_y": int((grad["axis"] == 1).sum())}
    back = read_aedat4(tmp_path / "run.aedat4")
    assert set(back) == set(counts)
    same(back["events"], dvs)
    same(back["events_gradient_x"], grad[grad["axis"] == 0])
    same(back["events_gradient_y"], grad[grad["axis"] == 1])
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no temporary file left


def test_cli_exports_one_stream_and_refuses_unknown_ones(emulation, tmp_path, capsys):
    path, dvs, _ = emulation
    out = tmp_path / "dvs.aedat4"
    assert main(["export", str(path), "--format", "aedat4", "--stream", "events", "--out", str(out)]) == 0
    back = read_aedat4(out)
    assert list(back) == ["events"]
    same(back["events"], dvs)
    assert main(["export", str(path), "--format", "aedat4", "--stream", "evnts", "--out", str(out)]) == 2
    assert "no stream 'evnts'" in capsys.readouterr().err
    with pytest.raises(ConfigError, match="no stream"):
        export_aedat4(path, out, streams=["nope"])


def test_a_reader_taking_the_first_event_stream_gets_the_dvs(tmp_path):
    """Issue 26: with a center-surround stream beside it, readers that take the first event stream
    (dv-processing's getNextEventBatch() without a name, tonic's read_aedat4) got the CSDVS events."""
    import dv_processing as dv

    dvs, cs = events(3000, BRIGHTNESS_DTYPE, 3), events(1000, BRIGHTNESS_DTYPE, 4)
    export_aedat4(write_run(tmp_path / "run.h5", events=dvs, csdvs_events=cs), tmp_path / "run.aedat4")
    recording = dv.io.MonoCameraRecording(str(tmp_path / "run.aedat4"))
    parts = []
    while (batch := recording.getNextEventBatch()) is not None:  # no name: the camera's (first) event stream
        parts.append(batch.numpy())
    same(np.concatenate(parts), dvs)
    assert read_aedat4(tmp_path / "run.aedat4")["events_csdvs"].shape == (1000,)


def test_tonics_own_reader_returns_the_dvs_stream(tmp_path):
    """tonic.io.read_aedat4 (through the ``aedat`` package) takes the event stream of lowest id: with a
    center-surround and a gradient stream beside it, that must be the DVS stream, every event equal."""
    pytest.importorskip("aedat", reason="tonic's AEDAT4 reader needs the aedat package (aedat4 extra)")
    tonic_io = pytest.importorskip("tonic.io")
    dvs, cs = events(3000, BRIGHTNESS_DTYPE, 5), events(1000, BRIGHTNESS_DTYPE, 6)
    grad = events(2000, GRADIENT_DTYPE, 7)
    run = write_run(tmp_path / "run.h5", csdvs_events=cs, gradient_events=grad, events=dvs)
    export_aedat4(run, tmp_path / "run.aedat4")
    got = tonic_io.read_aedat4(str(tmp_path / "run.aedat4"))
    assert len(got) == len(dvs)
    np.testing.assert_array_equal(got["t"], dvs["t"])
    np.testing.assert_array_equal(got["x"], dvs["x"])
    np.testing.assert_array_equal(got["y"], dvs["y"])
    np.testing.assert_array_equal(got["on"].astype(bool), dvs["p"] > 0)
