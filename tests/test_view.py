"""`gevsim view`: event pictures beside the ground truth, as PNG strips and GIF animations."""

from __future__ import annotations

import numpy as np
import pytest

from gevsim.cli import main
from gevsim.io import EventReader
from gevsim.view import LABEL_PX, SATURATE, render_windows, video_frames

iio = pytest.importorskip("imageio.v3")


def test_each_window_draws_its_own_events_and_the_ground_truth(good):
    with EventReader(good) as r:
        w, h, t_end = r.width, r.height, r.t_end_us
        dvs = r.read("events", t_start_us=0, t_end_us=1000)
    pictures, names = render_windows(good, window_us=1000, streams=["events", "gradient_events"])
    assert names == ["events", "gradient_events", "ground truth"]
    assert pictures.shape == (-(-t_end // 1000), LABEL_PX + h + 4, 3 * w + 4, 3)
    # A pixel with net ON events is blue, net OFF red; a pixel without events is the background.
    net = np.zeros((h, w))
    np.add.at(net, (dvs["y"], dvs["x"]), np.where(dvs["p"] > 0, 1, -1))
    panel = pictures[0, LABEL_PX:LABEL_PX + h, :w].astype(int)
    on, off, none = net >= SATURATE, net <= -SATURATE, net == 0
    assert (panel[on][:, 2] > panel[on][:, 0]).all() and (panel[off][:, 0] > panel[off][:, 2]).all()
    assert (panel[none] == 24).all()


def test_cli_writes_png_and_gif_and_explains_mp4(good, tmp_path, capsys):
    png, gif = tmp_path / "v.png", tmp_path / "v.gif"
    assert main(["view", str(good), "--out", str(png), "--window-ms", "1"]) == 0
    assert main(["view", str(good), "--out", str(gif), "--window-ms", "0.5", "--fps", "20"]) == 0
    strip = iio.imread(png)
    frames = iio.imread(gif, index=None)
    with EventReader(good) as r:
        windows = -(-r.t_end_us // 500)
    assert frames.shape[0] == windows and strip.shape[0] == min(8, -(-windows // 2)) * frames.shape[1]
    assert main(["view", str(good), "--out", str(png)]) == 0  # replaces its own picture
    mine = tmp_path / "holiday.png"
    iio.imwrite(mine, np.zeros((4, 4, 3), np.uint8))
    assert main(["view", str(good), "--out", str(mine)]) == 2  # never a picture it did not write
    capsys.readouterr()
    assert main(["view", str(good), "--out", str(tmp_path / "v.png"), "--streams", "evnts"]) == 2


def test_mp4_holds_every_window_as_the_gif_draws_it(good, tmp_path):
    """MP4 through imageio-ffmpeg (the plot extra): one video frame per window, the same pictures as the
    lossless GIF up to the codec's loss, and replaced only when it is gevsim's own video."""
    pytest.importorskip("imageio_ffmpeg", reason="MP4 needs imageio-ffmpeg (plot extra)")
    gif, mp4 = tmp_path / "v.gif", tmp_path / "v.mp4"
    assert main(["view", str(good), "--out", str(gif), "--window-ms", "0.5"]) == 0
    assert main(["view", str(good), "--out", str(mp4), "--window-ms", "0.5"]) == 0
    exact = iio.imread(gif, index=None)[..., :3].astype(float)
    video = iio.imread(mp4, index=None, extension=".mp4").astype(float)
    frames, k = video_frames(exact.astype(np.uint8))
    assert k > 1 and video.shape == frames.shape and frames.shape[1] % 16 == frames.shape[2] % 16 == 0
    h, w = exact.shape[1:3]  # the picture sits top-left, each of its pixels a k x k block
    centres = video[:, k // 2:h * k:k, k // 2:w * k:k]
    assert np.median(np.abs(centres - exact)) <= 2 and np.abs(centres - exact).mean() < 6
    assert main(["view", str(good), "--out", str(mp4), "--window-ms", "1"]) == 0  # its own video: replaced
    other = tmp_path / "holiday.mp4"
    other.write_bytes(b"\x00\x00\x00\x18ftypmp42" + bytes(64))
    assert main(["view", str(good), "--out", str(other)]) == 2
