"""Frame mode: events from frames exactly as in Lehtonen et al., and the file run_frames writes."""

import numpy as np
import pytest

from gevsim.emulation.frames import emulate_frames
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
