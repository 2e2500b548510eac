"""Frame mode's loaders: folders of images (+ timestamps.txt), videos, EVREAL sequences."""

import numpy as np
import pytest

from gevsim.errors import ConfigError
from gevsim.io.frames import load_evreal_frames, load_frame_folder, load_video

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
    two_events = np.zeros(2, BRIGHTNESS_DTYPE)  # EVREAL folders hold at least two events
    export_evreal(tmp_path / "seq", two_events, images, np.array([0, 5000, 10000]), width=6, height=4)
    frames, t = load_evreal_frames(tmp_path / "seq")
    np.testing.assert_array_equal(frames, images / 255.0)
    np.testing.assert_allclose(t, [0.0, 0.005, 0.01])
    export_evreal(tmp_path / "bare", two_events, None, None, width=6, height=4)
    with pytest.raises(ConfigError, match="no ground-truth images"):
        load_evreal_frames(tmp_path / "bare")


def _gray_picture():
    """Every 8-bit gray value once (16x16), in the four ways a gray picture is saved: L, RGB, RGBA, palette."""
    from PIL import Image

    img = Image.fromarray(np.arange(256, dtype=np.uint8).reshape(16, 16), "L")
    return {mode: img.convert(mode) for mode in ("L", "RGB", "RGBA", "P")}


def test_gray_rgb_rgba_and_palette_pictures_load_as_exactly_their_gray_values(tmp_path):
    # issue 36: the float Rec.601 sum of R = G = B = v is not always v, which moved gradient events
    want = np.arange(256).reshape(16, 16) / 255.0
    for mode, img in _gray_picture().items():
        (tmp_path / mode).mkdir()
        img.save(tmp_path / mode / "f0.png")
        img.save(tmp_path / mode / "f1.png")
        assert iio.imread(tmp_path / mode / "f0.png").ndim == (2 if mode == "L" else 3)
        frames, _ = load_frame_folder(tmp_path / mode, fps=10)
        np.testing.assert_array_equal(frames[0], want, err_msg=mode)
        np.testing.assert_array_equal(frames[1], want, err_msg=mode)


def test_colour_pixels_beside_gray_ones_keep_rec601_luma(tmp_path):
    rgb = np.zeros((2, 2, 3), np.uint8)
    rgb[0, 0] = (51, 51, 51)
    rgb[1, 1] = (255, 0, 0)
    iio.imwrite(tmp_path / "a.png", rgb)
    frames, _ = load_frame_folder(tmp_path, fps=1)
    assert frames[0, 0, 0] == 51 / 255 and frames[0, 0, 1] == 0.0
    assert frames[0, 1, 1] == pytest.approx(0.299)


@pytest.fixture
def small_memory(monkeypatch):
    """Memory for ``frames`` frames of 8x8 px (at FRAME_PX_BYTES a pixel), and a count of decoded frames."""
    from gevsim import _resources
    from gevsim.io import frames as loaders
    from gevsim.resources import FRAME_PX_BYTES

    decoded = []
    to_gray = loaders._to_gray

    def counting(img, **kw):
        decoded.append(img.shape)
        return to_gray(img, **kw)

    def allow(frames):
        budget = frames * 64 * FRAME_PX_BYTES
        monkeypatch.setattr(_resources, "usable_memory", lambda: (budget, "this machine has"))

    monkeypatch.setattr(loaders, "_to_gray", counting)
    return allow, decoded


def test_a_video_too_big_for_memory_is_refused_from_its_header_before_decoding(tmp_path, small_memory):
    pytest.importorskip("imageio_ffmpeg", reason="MP4 needs imageio-ffmpeg (plot extra)")
    allow, decoded = small_memory
    iio.imwrite(tmp_path / "v.mp4", np.zeros((10, 8, 8), np.uint8), fps=10, macro_block_size=1)
    allow(9)
    with pytest.raises(ConfigError, match=r"v\.mp4: the 10 frames of 8x8 px its metadata states need"):
        load_video(tmp_path / "v.mp4")
    assert decoded == []  # refused from the header alone
    allow(10)
    frames, t = load_video(tmp_path / "v.mp4")
    assert frames.shape == (10, 8, 8) and frames.dtype == np.float64 and len(decoded) == 10
    np.testing.assert_allclose(t, np.arange(10) / 10)


def test_a_video_without_a_frame_count_stops_decoding_at_the_memory_budget(tmp_path, small_memory):
    allow, decoded = small_memory
    video = np.zeros((40, 8, 8), np.uint8)
    video[::2] = 255  # every frame differs from the last: the GIF keeps all 40
    iio.imwrite(tmp_path / "v.gif", video, loop=0)
    allow(20)
    with pytest.raises(ConfigError, match=r"v\.gif: the first 21 frames of 8x8 px \(decoding stopped there"):
        load_video(tmp_path / "v.gif", fps=10)
    assert len(decoded) == 21  # not one frame more
    allow(40)
    frames, _ = load_video(tmp_path / "v.gif", fps=10)
    np.testing.assert_array_equal(frames, video / 255.0)
