"""Video and frame mode at any frame rate (issue 36, item 4): a 30 or 29.97 fps clip rarely spans a whole
number of 20 us steps; through a sensor it is emulated for its span rounded down to whole steps, the light
still interpolated between the real frame times. Gray RGB, palette and L pictures give the same events."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gevsim.cli import main
from gevsim.emulation.frame_sensor import frame_setup, whole_steps
from gevsim.errors import ConfigError
from gevsim.io import EventReader
from gevsim.pixel import load_preset
from gevsim.timebase import TimeGrid

iio = pytest.importorskip("imageio.v3")

STEP_S = TimeGrid.step_s
NTSC = 30000 / 1001  # 29.97 fps


@pytest.mark.parametrize("fps", [30.0, NTSC, 24000 / 1001, 25.0, 60.0, 1e3 / 7])
def test_any_clip_length_is_emulated_for_its_span_rounded_down_to_whole_steps(fps):
    grid = TimeGrid(step_s=STEP_S)
    for n_frames in range(2, 61):
        span = (n_frames - 1) / fps
        duration = whole_steps(span, STEP_S, source="clip.mp4")
        assert duration <= span + 1e-12 and span - duration < STEP_S  # never past the last frame, < 1 step cut
        assert grid.steps(duration) == math.floor(span / STEP_S + 1e-6)  # a whole number of steps: no FieldError


def test_a_span_of_whole_steps_is_kept_and_a_too_short_one_refused():
    assert whole_steps(0.1, STEP_S, source="x") == 0.1  # 4 frames at 30 fps: 5000 steps exactly
    assert whole_steps(29 / 30, STEP_S, source="x") == 48333 * STEP_S  # the README's 30-frame clip
    with pytest.raises(ConfigError, match="less than two steps"):
        whole_steps(3e-5, STEP_S, source="x")  # 2 frames of a 33 kfps clip


def test_the_light_stays_at_the_real_frame_times():
    t = np.arange(3) / NTSC
    frames = np.stack([np.full((2, 2), v) for v in (0.2, 0.6, 0.4)])
    setup = frame_setup(frames, t + 5.0, preset=load_preset("davis346"), illuminance_lux=5.0, source="clip.mp4")
    np.testing.assert_array_equal(setup.basis_times_s, t + 5.0 - 5.0)  # the poses are not stretched or moved
    assert setup.duration_s == 3336 * STEP_S < t[-1]
    with pytest.raises(ConfigError, match="at least two frames"):
        frame_setup(frames[:1], t[:1], preset=load_preset("davis346"), illuminance_lux=5.0, source="clip.mp4")


@pytest.mark.parametrize("fps, n_frames", [(30.0, 2), (NTSC, 3)])
def test_readme_video_line_works_at_30_and_29_97_fps(fps, n_frames, tmp_path, capsys):
    pytest.importorskip("imageio_ffmpeg", reason="MP4 needs imageio-ffmpeg (plot extra)")
    video = np.zeros((n_frames, 8, 8), np.uint8)
    video[1, :, 4:] = 200
    video[2:] = 120
    clip, out = tmp_path / "clip.mp4", tmp_path / "out.h5"
    iio.imwrite(clip, video, fps=fps, macro_block_size=1)
    assert main(["emulate", "--video", str(clip), "--sensor", "davis346", "--illuminance-lux", "5",
                 "--emulators", "dvs", "--out", str(out), "-q"]) == 0
    span = (n_frames - 1) / iio.immeta(clip)["fps"]  # the rate the container states (29.97 for 30000/1001)
    steps = math.floor(span / STEP_S + 1e-6)
    with EventReader(out) as r:
        events = r.read("events")
        assert r.t_end_us == round(steps * STEP_S * 1e6) <= span * 1e6
        assert len(events) > 0 and events["t"].max() <= r.t_end_us
    err = capsys.readouterr().err
    assert f"{steps} steps of 20 us" in err
    assert ("rounded down to whole steps" in err) == (abs(span / STEP_S - steps) > 1e-6 * steps)


def test_absurd_illuminance_is_one_line_naming_the_flag_before_any_frame_is_read(tmp_path, capsys):
    assert main(["emulate", "--video", str(tmp_path / "none.mp4"), "--sensor", "davis346",
                 "--illuminance-lux", "1e30", "--out", str(tmp_path / "o.h5")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("gevsim: error: --illuminance-lux must be") and "\n" not in err


def test_gray_l_rgb_and_palette_frames_give_identical_events(tmp_path):
    from PIL import Image
    from skimage import data

    g = data.camera()[::8, ::8]  # issue 36: 324 gradient events from RGB/palette, 216 from L
    counts = {}
    for mode in ("L", "RGB", "P"):
        folder = tmp_path / mode
        folder.mkdir()
        for k in range(3):
            Image.fromarray(np.roll(g, 3 * k, axis=1), "L").convert(mode).save(folder / f"f{k}.png")
        assert main(["emulate", "--frames", str(folder), "--fps", "30", "--out", str(tmp_path / f"{mode}.h5"),
                     "-q"]) == 0
        with EventReader(tmp_path / f"{mode}.h5") as r:
            counts[mode] = {name: r.read(name) for name in ("events", "gradient_events", "gradient_rc_events")}
    for mode in ("RGB", "P"):
        for name, events in counts["L"].items():
            assert len(events) > 0
            np.testing.assert_array_equal(counts[mode][name], events, err_msg=f"{mode} {name}")
