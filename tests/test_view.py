"""`gevsim view`: event pictures beside the ground truth, as PNG strips and GIF animations."""

from __future__ import annotations

import numpy as np
import pytest

from gevsim.cli import main
from gevsim.io import EventReader
from gevsim.view import (
    BAR_PX,
    GAP_PX,
    LABEL_PX,
    PANEL_MIN_PX,
    SATURATE,
    VIDEO_MIN_WIDTH,
    header,
    panel_scale,
    render_windows,
    stream_title,
    video_frames,
    window_label,
)

iio = pytest.importorskip("imageio.v3")


def test_each_window_draws_its_own_events_and_the_ground_truth(good):
    with EventReader(good) as r:
        w, h, t_end = r.width, r.height, r.t_end_us
        dvs = r.read("events", t_start_us=0, t_end_us=1000)
    pictures, names = render_windows(good, window_us=1000, streams=["events", "gradient_events"])
    assert names == ["events", "gradient_events", "ground truth"]
    k = panel_scale(w)  # each sensor pixel a k x k block, a panel at least PANEL_MIN_PX wide
    assert k == 13 and w * k >= PANEL_MIN_PX > w * (k - 1)
    assert pictures.shape == (-(-t_end // 1000), LABEL_PX + h * k + BAR_PX, 3 * w * k + 2 * GAP_PX, 3)
    big = pictures[0, LABEL_PX:LABEL_PX + h * k, :w * k]
    panel = big[::k, ::k].astype(int)
    assert (big == panel.repeat(k, axis=0).repeat(k, axis=1)).all()  # nearest neighbour: no blending
    # A pixel with net ON events is blue, net OFF red; a pixel without events is the background.
    net = np.zeros((h, w))
    np.add.at(net, (dvs["y"], dvs["x"]), np.where(dvs["p"] > 0, 1, -1))
    on, off, none = net >= SATURATE, net <= -SATURATE, net == 0
    assert (panel[on][:, 2] > panel[on][:, 0]).all() and (panel[off][:, 0] > panel[off][:, 2]).all()
    assert (panel[none] == 24).all()


def test_each_row_is_labelled_with_its_window_and_the_streams_human_names(good):
    """The strip above each row gives that row's time span and the panels' names (DVS, not `events`)."""
    assert window_label(18000, 18250) == "18.00-18.25 ms" and window_label(1000, 1125) == "1.000-1.125 ms"
    assert [stream_title(s) for s in ("events", "gradient_rc_events", "csdvs_events", "mine")] == \
        ["DVS", "gradient RC", "CSDVS", "mine"]
    with EventReader(good) as r:
        k = panel_scale(r.width)
        panel = r.width * k
    pictures, names = render_windows(good, window_us=250, start_us=1000, count=3)
    assert names[:2] == ["events", "gradient_events"]  # DVS first, then the emulators' order
    titles = [stream_title(n) for n in names]
    assert titles == ["DVS", "gradient", "ground truth"]
    for i, picture in enumerate(pictures):
        a = 1000 + 250 * i
        assert (picture[:LABEL_PX] == header(window_label(a, a + 250), titles, panel, picture.shape[1])).all()
    assert (pictures[0, :LABEL_PX] != pictures[1, :LABEL_PX]).any()  # the labels differ: the check is not vacuous
    assert not (pictures[0, :LABEL_PX] == header("", titles, panel, pictures.shape[2])).all()


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
    assert frames.shape[2] >= VIDEO_MIN_WIDTH and video.shape == frames.shape
    assert frames.shape[1] % 16 == frames.shape[2] % 16 == 0
    h, w = exact.shape[1:3]  # the picture sits top-left, each of its pixels a k x k block
    centres = video[:, k // 2:h * k:k, k // 2:w * k:k]
    assert np.median(np.abs(centres - exact)) <= 2 and np.abs(centres - exact).mean() < 6
    assert main(["view", str(good), "--out", str(mp4), "--window-ms", "1"]) == 0  # its own video: replaced
    other = tmp_path / "holiday.mp4"
    other.write_bytes(b"\x00\x00\x00\x18ftypmp42" + bytes(64))
    assert main(["view", str(good), "--out", str(other)]) == 2
