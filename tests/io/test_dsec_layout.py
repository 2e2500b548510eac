"""The brightness stream in DSEC's layout: DSEC's EventSlicer logic reads a gevsim emulation; every
dataset says its units and meaning; files of the former format are still read."""

import math
from pathlib import Path

import h5py
import numpy as np
import pytest

from gevsim.emulation import load_config, run, run_frames
from gevsim.evaluation import reconstruct_file
from gevsim.events.types import BRIGHTNESS_DTYPE
from gevsim.io import EventReader
from gevsim.io.hdf5 import READABLE_FORMATS

DATA = Path(__file__).parents[1] / "data"
META = dict(width=64, height=48, config_toml="[sensor]\nwidth = 64\n", seed=7)


def brute_ms_to_idx(t, t_end_us):
    """ms_to_idx by its definition: the index of the first event with t >= k ms, k = 0 .. ceil(t_end)."""
    return np.array([np.searchsorted(t, k * 1000, side="left") for k in range(math.ceil(t_end_us / 1000) + 1)])


class DsecSlicer:
    """The logic of DSEC's ``EventSlicer`` (github.com/uzh-rpg/DSEC, ``scripts/utils/eventslicer.py``),
    written here from the layout it documents: ``events/{p,x,y,t}``, a root ``ms_to_idx`` with
    ``t[ms_to_idx[ms]] >= 1000 ms`` and ``t[ms_to_idx[ms] - 1] < 1000 ms``, and an optional root
    ``t_offset`` (us) added to ``t``. A window [t_start, t_end) is first cut on whole milliseconds
    through ``ms_to_idx`` (None when its end lies beyond the table), then to the microsecond."""

    def __init__(self, f: h5py.File):
        self.events = {name: f[f"events/{name}"] for name in ("p", "x", "y", "t")}
        self.ms_to_idx = np.asarray(f["ms_to_idx"], dtype="int64")
        self.t_offset = int(f["t_offset"][()]) if "t_offset" in f else 0
        self.t_final = int(self.events["t"][-1]) + self.t_offset

    def get_events(self, t_start_us: int, t_end_us: int):
        assert t_start_us < t_end_us
        start, end = t_start_us - self.t_offset, t_end_us - self.t_offset
        ms_start, ms_end = math.floor(start / 1000), math.ceil(end / 1000)
        if ms_end >= self.ms_to_idx.size:
            return None
        lo, hi = self.ms_to_idx[ms_start], self.ms_to_idx[ms_end]
        t = np.asarray(self.events["t"][lo:hi])
        a, b = np.searchsorted(t, start, side="left"), np.searchsorted(t, end, side="left")
        out = {"t": t[a:b] + self.t_offset}
        for name in ("p", "x", "y"):
            out[name] = np.asarray(self.events[name][lo + a:lo + b])
        return out


@pytest.fixture(scope="module")
def emulation(tmp_path_factory):
    """A rendered card scene, davis346 noise, APS frames: every kind of dataset the driver writes (with an
    unlimited bus: the chip's bus per pixel would queue most of this small moving card's events)."""
    tmp = tmp_path_factory.mktemp("dsec")
    cfg = tmp / "run.toml"
    cfg.write_text(f'[emulation]\nscene = "{DATA / "card.toml"}"\nsensor = "davis346"\nseed = 4\nstep_s = 2e-5\n'
                   'frame_rate_hz = 1000.0\naps = true\naps_exposure_s = 5e-4\n'
                   'emulators = ["dvs", "gradient", "gradient_rc", "csdvs"]\n[render]\nwidth = 32\nheight = 24\n'
                   '[sensor]\nmax_rate_eps = inf\n')
    run(load_config(cfg), tmp / "run.h5", cache_dir=tmp / "cache")
    return tmp / "run.h5"


def test_dsec_event_slicer_reads_the_brightness_stream(emulation):
    with EventReader(emulation) as r:
        events = r.read("events")
        t_end = r.t_end_us
    assert len(events) > 1000 and events["p"].any() and not events["p"].all()
    with h5py.File(emulation, "r") as f:
        slicer = DsecSlicer(f)
        assert slicer.t_offset == 0 and slicer.t_final == events["t"][-1]
        assert f["events/p"].dtype == np.uint8 and f["events/p"].id.get_type().get_class() == h5py.h5t.INTEGER
        np.testing.assert_array_equal(slicer.ms_to_idx, brute_ms_to_idx(events["t"], t_end))
        for start, end in [(0, t_end), (0, 1), (1234, 2345), (999, 3001), (2000, 2000 + 1000), (t_end - 7, t_end)]:
            got = slicer.get_events(start, end)
            want = events[(events["t"] >= start) & (events["t"] < end)]
            np.testing.assert_array_equal(got["t"], want["t"])
            np.testing.assert_array_equal(got["x"], want["x"])
            np.testing.assert_array_equal(got["y"], want["y"])
            np.testing.assert_array_equal(got["p"], want["p"].astype(np.uint8))  # 1 = ON, 0 = OFF
        assert slicer.get_events(0, t_end + 1000) is None  # beyond the table: DSEC's "cannot guarantee"


def _datasets(path):
    with h5py.File(path, "r") as f:
        found = []
        f.visititems(lambda name, obj: found.append((name, dict(obj.attrs))) if isinstance(obj, h5py.Dataset)
                     else None)
        return found


def test_every_dataset_states_its_units_and_meaning(emulation, tmp_path):
    frames = np.random.default_rng(0).random((3, 8, 10))
    run_frames(frames, np.array([0.0, 0.01, 0.02]), tmp_path / "frames.h5")
    for path in (emulation, tmp_path / "frames.h5"):
        found = _datasets(path)
        for name, attrs in found:
            assert attrs.get("units") and attrs.get("meaning"), f"{path.name}:{name} lacks units or meaning"
    assert {"frames/intensity/images", "events/p", "gradient_events/axis", "thresholds/gradient",
            "initial_state/gradient"} <= {name for name, _ in _datasets(tmp_path / "frames.h5")}
    attrs = dict(_datasets(emulation))
    assert {"csdvs_events/p", "gradient_rc_events/ms_to_idx", "t_offset", "frames/aps/t"} <= set(attrs)
    assert attrs["events/t"]["units"] == "us" and attrs["frames/log_photocurrent/images"]["units"] == "ln(A)"
    assert attrs["frames/aps/images"]["units"] == "DN" and attrs["thresholds/gradient"]["units"] == "ln"


def write_format_1(path, events, *, t_end_us):
    """A file as gevsim wrote it before the DSEC layout (format gevsim-events-1): the polarity as
    h5py stores a numpy bool (an HDF5 enum), ms_to_idx only inside the group, no t_offset."""
    with h5py.File(path, "w") as f:
        f.attrs.update(width=META["width"], height=META["height"], config_toml=META["config_toml"],
                       seed=META["seed"], gevsim_version="0.1.0", format="gevsim-events-1", complete=True,
                       t_end_us=np.int64(t_end_us))
        g = f.create_group("events")
        g.attrs["kind"], g.attrs["fields"] = "events", ["x", "y", "t", "p"]
        for name in ("x", "y", "t", "p"):
            g.create_dataset(name, data=events[name], maxshape=(None,), chunks=True)
        g.create_dataset("ms_to_idx", data=brute_ms_to_idx(events["t"], t_end_us).astype(np.int64))


def test_files_of_the_former_format_are_still_read(tmp_path):
    rng = np.random.default_rng(1)
    ev = np.zeros(500, BRIGHTNESS_DTYPE)
    ev["t"] = np.sort(rng.integers(0, 9000, 500))
    ev["x"], ev["y"], ev["p"] = rng.integers(0, 64, 500), rng.integers(0, 48, 500), rng.random(500) < 0.5
    write_format_1(tmp_path / "old.h5", ev, t_end_us=9500)
    with h5py.File(tmp_path / "old.h5", "r") as f:
        assert f["events/p"].id.get_type().get_class() == h5py.h5t.ENUM  # h5py's bool: an HDF5 enum
        with pytest.raises(KeyError, match="ms_to_idx"):  # what DSEC's slicer met: no root ms_to_idx
            DsecSlicer(f)
    with EventReader(tmp_path / "old.h5") as r:
        assert r.dtype("events") == BRIGHTNESS_DTYPE
        np.testing.assert_array_equal(r.read("events"), ev)
        np.testing.assert_array_equal(r.read("events", 1000, 2000), ev[(ev["t"] >= 1000) & (ev["t"] < 2000)])
    assert READABLE_FORMATS == ("gevsim-events-1", "gevsim-events-2")


def test_new_files_read_back_the_same_events_and_reconstructions(emulation):
    with EventReader(emulation) as r:
        assert r.dtype("events") == BRIGHTNESS_DTYPE and r.dtype("csdvs_events") == BRIGHTNESS_DTYPE
        ev = r.read("events", 1000, 3000)
    assert ev.dtype == BRIGHTNESS_DTYPE and set(np.unique(ev["p"])) == {False, True}
    rec, gt, _ = reconstruct_file(emulation, "complementary")
    assert rec.frames.shape == gt.shape and np.isfinite(rec.frames).all()
