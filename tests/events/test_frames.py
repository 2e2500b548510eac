"""Frame mode: loaders, and events from frames exactly as in Lehtonen et al."""

import numpy as np
import pytest

from gevsim.errors import ConfigError
from gevsim.events import GradientEmulator, decode, encode, gradients, ternary, threshold_matrix
from gevsim.events.frames import emulate_frames, load_evreal_frames, load_frame_folder, load_video
from gevsim.events.gradient import PAPER_THRESHOLDS

iio = pytest.importorskip("imageio.v3")


def _write_pngs(folder, frames_u8, times=None):
    for k, f in enumerate(frames_u8):
        iio.imwrite(folder / f"frame_{k}.png", f)
    if times is not None:
        (folder / "timestamps.txt").write_text("".join(f"{t!r}\n" for t in times))


def test_png_folder_round_trips_exactly(tmp_path, rng):
    # 12 frames named frame_0 .. frame_11: natural order puts frame_2 before frame_10.
    frames = rng.integers(0, 256, (12, 6, 8), dtype=np.uint8)
    times = [0.1 * k + 0.05 for k in range(12)]
    _write_pngs(tmp_path, frames, times)
    got, t = load_frame_folder(tmp_path)
    assert got.dtype == np.float64 and got.shape == (12, 6, 8)
    np.testing.assert_array_equal(got, frames / 255.0)
    np.testing.assert_array_equal(t, times)


def test_16_bit_and_colour_frames_and_fps(tmp_path):
    a = np.full((4, 5), 65535, np.uint16)
    a[0, 0] = 0
    iio.imwrite(tmp_path / "a.png", a)
    rgb = np.zeros((4, 5, 3), np.uint8)
    rgb[..., 0] = 255  # pure red -> Rec.601 luma 0.299
    iio.imwrite(tmp_path / "b.png", rgb)
    got, t = load_frame_folder(tmp_path, fps=25.0)
    assert got[0, 0, 0] == 0.0 and got[0, 1, 1] == 1.0
    np.testing.assert_allclose(got[1], 0.299)
    np.testing.assert_allclose(t, [0.0, 0.04])


def test_folder_errors_name_the_file(tmp_path):
    with pytest.raises(ConfigError, match="no image files"):
        load_frame_folder(tmp_path, fps=10)
    _write_pngs(tmp_path, np.zeros((2, 4, 4), np.uint8))
    with pytest.raises(ConfigError, match="give fps") as err:
        load_frame_folder(tmp_path)
    assert str(tmp_path) in str(err.value)
    (tmp_path / "timestamps.txt").write_text("0.0\n0.1\n0.2\n")
    with pytest.raises(ConfigError, match="3 timestamps for 2 frames"):
        load_frame_folder(tmp_path)
    (tmp_path / "timestamps.txt").write_text("0.1\n0.1\n")
    with pytest.raises(ConfigError, match="increase strictly") as err:
        load_frame_folder(tmp_path)
    assert "timestamps.txt" in str(err.value)
    iio.imwrite(tmp_path / "frame_9.png", np.zeros((4, 6), np.uint8))
    with pytest.raises(ConfigError, match="differs") as err:
        load_frame_folder(tmp_path, fps=10)
    assert "frame_9.png" in str(err.value)


def test_video_frames_and_fps(tmp_path):
    video = np.zeros((3, 8, 8), np.uint8)
    video[1, :, 4:] = 255
    video[2] = 255
    iio.imwrite(tmp_path / "v.gif", video, loop=0)
    frames, t = load_video(tmp_path / "v.gif", fps=10.0)
    np.testing.assert_allclose(frames, video / 255.0, atol=1e-12)
    np.testing.assert_allclose(t, [0.0, 0.1, 0.2])
    with pytest.raises(ConfigError, match="frame rate"):
        load_video(tmp_path / "v.gif")


def test_evreal_frames(tmp_path, rng):
    from gevsim.events.types import BRIGHTNESS_DTYPE
    from gevsim.io.evreal import export_evreal

    images = rng.integers(0, 256, (3, 4, 6), dtype=np.uint8)
    export_evreal(tmp_path / "seq", np.zeros(0, BRIGHTNESS_DTYPE), images, np.array([0, 5000, 10000]),
                  width=6, height=4)
    frames, t = load_evreal_frames(tmp_path / "seq")
    np.testing.assert_array_equal(frames, images / 255.0)
    np.testing.assert_allclose(t, [0.0, 0.005, 0.01])
    export_evreal(tmp_path / "bare", np.zeros(0, BRIGHTNESS_DTYPE), None, None, width=6, height=4)
    with pytest.raises(ConfigError, match="no ground-truth images"):
        load_evreal_frames(tmp_path / "bare")


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
    initial = GradientEmulator((8, 10), thresholds=PAPER_THRESHOLDS, rc=rc).ternary_of(frames[0])
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
    with pytest.raises(ValueError, match="2 values are NaN"):
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
