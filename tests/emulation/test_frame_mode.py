"""Frame mode: events from frames exactly as in Lehtonen et al., and the file run_frames writes."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gevsim import _portable as pm
from gevsim.emulation.frames import LINLOG_THRESHOLD, emulate_frames, file_log_mode, linear_intensity, log_intensity
from gevsim.events import GradientEmulator, decode, encode, gradients, ternary, threshold_matrix
from gevsim.events.gradient import PAPER_THRESHOLDS


@pytest.mark.parametrize("rc", [False, True])
def test_gradient_events_are_the_papers_dense_encoding(rng, rc):
    frames = rng.random((6, 8, 10))
    t_s = np.arange(6) * 0.01 + 0.5
    name = "gradient_rc" if rc else "gradient"
    ev = emulate_frames(frames, t_s, emulators=[name], rng=rng)[name + "_events"]
    theta = threshold_matrix((8, 10), PAPER_THRESHOLDS)

    def tern(img):
        gx, gy = gradients(img, rc=rc)
        t = np.stack([ternary(gx, theta), ternary(gy, theta)])
        if rc:  # one comparator per pair, at the even position
            t[0, :, 1::2] = 0
            t[1, 1::2, :] = 0
        return t

    expected = set()
    for k in range(1, len(frames)):
        e = encode(tern(frames[k - 1]), tern(frames[k]))
        for a, y, x in zip(*np.nonzero(e)):
            expected.add((int(np.rint(t_s[k] * 1e6)), int(a), int(y), int(x), int(e[a, y, x])))
    got = {(int(t), int(a), int(y), int(x), int(p)) for t, a, y, x, p in
           zip(ev["t"], ev["axis"], ev["y"], ev["x"], ev["p"])}
    assert len(got) == len(ev) and len(ev) > 0  # at most one event per comparator per frame
    assert got == expected
    assert set(ev["t"].tolist()) <= set(np.rint(t_s * 1e6).astype(int).tolist())
    # Lossless: decoding from the first frame's state gives the last frame's ternary gradients.
    initial = GradientEmulator((8, 10), thresholds_ln=PAPER_THRESHOLDS, rc=rc).ternary_of(frames[0])
    np.testing.assert_array_equal(decode(ev, initial), tern(frames[-1]))


def test_log_ramp_gives_floor_d_over_theta_dvs_events(rng):
    d = np.linspace(0.1, 1.5, 15).reshape(3, 5) + 0.013  # ln change per pixel, off threshold multiples
    eps = 1 / 255
    base = np.log(0.05 + eps)
    frames = np.stack([np.exp(base + d * s) - eps for s in np.linspace(0.0, 1.0, 7)])
    t_s = np.linspace(0.0, 0.06, 7)
    ev = emulate_frames(frames, t_s, emulators=["dvs"], rng=rng)["events"]
    counts = np.zeros((3, 5), int)
    np.add.at(counts, (ev["y"], ev["x"]), 1)
    np.testing.assert_array_equal(counts, np.floor(d / 0.2).astype(int))
    assert ev["p"].all()
    # Timestamps interpolated between frames, not stamped at frame times.
    assert not set(ev["t"].tolist()) <= set(np.rint(t_s * 1e6).astype(int).tolist())


def test_uniform_additive_change_gives_dvs_but_no_gradient_events(rng):
    base = rng.integers(0, 129, (8, 10)) / 256.0  # dyadic values: adding 1/4 is exact
    frames = np.stack([base + c for c in (0.0, 0.125, 0.25, 0.375, 0.5)])
    out = emulate_frames(frames, np.arange(5) / 30.0, rng=rng)
    assert len(out["gradient_events"]) == 0 and len(out["gradient_rc_events"]) == 0
    dvs = out["events"]
    assert dvs["p"].all()
    assert len(np.unique(dvs["y"].astype(int) * 10 + dvs["x"])) == 80  # every pixel fired ON


def test_input_errors(rng):
    good = rng.random((3, 4, 6))
    t = np.array([0.0, 0.1, 0.2])
    with pytest.raises(ValueError, match="increase strictly: frame 2"):
        emulate_frames(good, [0.0, 0.2, 0.1], rng=rng)
    with pytest.raises(ValueError, match="shape \\(3,\\)"):
        emulate_frames(good, [0.0, 0.1], rng=rng)
    bad = good.copy()
    bad[1, 2, 3] = bad[2, 0, 0] = np.nan
    with pytest.raises(ValueError, match=r"frames has 2 non-finite value\(s\)"):
        emulate_frames(bad, t, rng=rng)
    with pytest.raises(ValueError, match="even height and width, got 3x6"):
        emulate_frames(good[:, :3], t, emulators=["gradient_rc"], rng=rng)
    assert len(emulate_frames(good[:, :3], t, emulators=["gradient"], rng=rng)) == 1  # odd size fine without RC
    with pytest.raises(ValueError, match="N >= 2"):
        emulate_frames(good[:1], t[:1], rng=rng)
    with pytest.raises(ValueError, match="did you mean 'gradient'"):
        emulate_frames(good, t, emulators=["gradiant"], rng=rng)
    with pytest.raises(TypeError, match="divide 8-bit"):
        emulate_frames((good * 255).astype(np.uint8), t, rng=rng)


def test_run_frames_writes_events_ground_truth_and_decoding_state(tmp_path, rng):
    from gevsim.emulation import layout, run_frames
    from gevsim.io import EventReader

    frames = rng.random((4, 6, 8))
    t_s = np.arange(4) / 30.0
    summary = run_frames(frames, t_s, tmp_path / "f.h5", seed=3, source="synthetic")
    with EventReader(tmp_path / "f.h5") as r:
        assert {s: len(r.read(s)) for s in r.streams} == summary["counts"]
        images, t_us = r.frames(layout.INTENSITY)
        np.testing.assert_array_equal(images, frames.astype(np.float32))
        assert list(t_us) == [0, 33333, 66667, 100000]
        for name, rc in (("gradient", False), ("gradient_rc", True)):
            state = r.array(layout.initial_state_key(name))
            em = GradientEmulator((6, 8), thresholds_ln=PAPER_THRESHOLDS, rc=rc, interpolate=False)
            np.testing.assert_array_equal(state, em.ternary_of(frames[0]))
            np.testing.assert_array_equal(decode(r.read(f"{name}_events"), state), em.ternary_of(frames[-1]))
        assert r.attrs["mode"] == "frames" and r.seed == 3


# The log frame mode's DVS sees: "offset" ln(f + 1/255) (default) or v2e-style "linlog".

A = LINLOG_THRESHOLD


@settings(max_examples=200, deadline=None)
@given(f=st.floats(min_value=20 / 255, max_value=1e6, allow_nan=False))
def test_linlog_is_the_pure_log_at_and_above_the_threshold(f):
    assert log_intensity(np.array([f]), log_mode="linlog")[0] == pm.log(np.float64(f))  # the portable log


def test_linlog_is_linear_below_and_continuous_in_value_and_slope():
    assert A == 20 / 255  # v2e's 20 DN
    below = np.linspace(0.0, A, 50, endpoint=False)
    y = log_intensity(below, log_mode="linlog")
    np.testing.assert_allclose(np.diff(y) / np.diff(below), 1 / A, rtol=1e-9)  # a line of the log's slope at A
    for h in (1e-6, 1e-8):
        lo, at, hi = log_intensity(np.array([A - h, A, A + h]), log_mode="linlog")
        assert abs(at - np.log(A)) < 1e-15 and abs(lo - at) < 2 * h / A and abs(hi - at) < 2 * h / A
        np.testing.assert_allclose([(at - lo) / h, (hi - at) / h], 1 / A, rtol=10 * h / A)
    assert np.isfinite(log_intensity(np.zeros(1), log_mode="linlog")).all()  # black stays finite


@pytest.mark.parametrize("mode", ["offset", "linlog"])
def test_linear_intensity_inverts_log_intensity(mode):
    f = np.concatenate([[0.0], np.geomspace(1e-4, 1.0, 200)])
    np.testing.assert_allclose(linear_intensity(log_intensity(f, log_mode=mode), log_mode=mode), f,
                               rtol=1e-12, atol=1e-15)
    np.testing.assert_array_equal(log_intensity(f), pm.log(f + 1 / 255))  # the default, as before


def test_linlog_ramp_counts_are_the_pure_log_ones_and_offset_compresses_them(rng):
    # Per pixel a log ramp from f0 to f1 = f0 exp(d): a pure log gives floor(d / 0.2) ON events.
    f0 = np.array([[20 / 255, 0.1, 0.2, 0.5], [25 / 255, 0.15, 0.3, 0.08]])
    d = np.array([[0.45, 0.93, 1.31, 0.29], [1.57, 0.61, 0.85, 1.99]])  # off the multiples of 0.2
    frames = np.stack([f0 * np.exp(d * s) for s in np.linspace(0.0, 1.0, 9)])
    t_s = np.linspace(0.0, 0.08, 9)

    def counts(**kw):
        ev = emulate_frames(frames, t_s, emulators=["dvs"], rng=rng, **kw)["events"]
        assert ev["p"].all()
        c = np.zeros(f0.shape, int)
        np.add.at(c, (ev["y"], ev["x"]), 1)
        return c

    np.testing.assert_array_equal(counts(log_mode="linlog"), np.floor(d / 0.2).astype(int))
    eps = 1 / 255
    offset = counts()
    np.testing.assert_array_equal(offset, np.floor(np.log((f0 * np.exp(d) + eps) / (f0 + eps)) / 0.2).astype(int))
    assert (offset <= np.floor(d / 0.2)).all() and offset.sum() < np.floor(d / 0.2).sum()


def test_log_mode_errors(rng):
    frames, t = rng.random((3, 4, 6)), np.array([0.0, 0.1, 0.2])
    with pytest.raises(ValueError, match="log_mode must be one of 'offset', 'linlog', got 'lin'"):
        emulate_frames(frames, t, log_mode="lin", rng=rng)
    with pytest.raises(ValueError, match="linlog_threshold"):
        log_intensity(frames, log_mode="linlog", linlog_threshold=0.0)


def test_run_frames_records_linlog_and_reconstruction_inverts_it(tmp_path, rng):
    import shutil

    import h5py

    from gevsim.emulation import run_frames
    from gevsim.evaluation import reconstruct_file
    from gevsim.evaluation.methods import METHODS
    from gevsim.evaluation.runner import ground_truth
    from gevsim.io import EventReader

    frames = 0.5 + 0.3 * rng.random((5, 12, 16))
    frames[:, :, :8] *= np.exp(-np.linspace(0.0, 4.0, 5))[:, None, None]  # the left half goes dark
    t_s = np.arange(5) / 30.0
    run_frames(frames, t_s, tmp_path / "offset.h5", source="synthetic")
    run_frames(frames, t_s, tmp_path / "linlog.h5", source="synthetic", log_mode="linlog")
    with EventReader(tmp_path / "offset.h5") as r:
        assert "log_mode" not in r.attrs and file_log_mode(r.attrs) == {"log_mode": "offset"}
    with EventReader(tmp_path / "linlog.h5") as r:
        assert (r.attrs["log_mode"], r.attrs["linlog_threshold"]) == ("linlog", A)
        assert 'log_mode = "linlog"' in r.attrs["config_toml"]
        assert file_log_mode(r.attrs) == {"log_mode": "linlog", "linlog_threshold": A}
    # The same events read as an offset file: the direct method's log estimate y comes back as
    # exp(y) - 1/255 there, and from the linlog file as exp(y) at and above ln(20/255), on the tangent
    # below. (reconstruct_file then shifts every frame to the ground truth's mean.)
    shutil.copy(tmp_path / "linlog.h5", tmp_path / "as_offset.h5")
    with h5py.File(tmp_path / "as_offset.h5", "r+") as f:
        del f.attrs["log_mode"], f.attrs["linlog_threshold"]

    def direct(name):
        with EventReader(tmp_path / name) as r:
            gt, t_us, is_log = ground_truth(r)
            assert not is_log
            return METHODS["direct"].run(r, gt, t_us, c=1.0, contrast_ln=None, is_log=is_log)

    lin, off = direct("linlog.h5"), direct("as_offset.h5")
    y = np.log(off + 1 / 255)
    assert lin.shape == frames.shape and (y < np.log(A)).any() and (y > np.log(A)).any()  # both pieces
    np.testing.assert_allclose(lin, linear_intensity(y, log_mode="linlog"), rtol=1e-12)
    reconstruct_file(tmp_path / "linlog.h5", "direct")  # and the whole path runs
