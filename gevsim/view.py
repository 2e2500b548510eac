"""``gevsim view``: see what a sensor made of a scene, as event frames beside the ground truth.

Each time window (``window_us``) becomes one picture with a panel per stream, side by side with the
ground-truth log frame nearest the window's end (tone-mapped from the run's own range). Each sensor
pixel is drawn as a block of ``k`` x ``k`` picture pixels (nearest neighbour; ``k`` the least making a
panel :data:`PANEL_MIN_PX` wide, at most :data:`MAX_SCALE`); above the panels a strip gives the window's
time (``18.00-18.25 ms``) and the streams' names (DVS, gradient, gradient RC, CSDVS), and under them a
bar shows where the window lies in the file:

- brightness streams (DVS, CSDVS): per pixel, the net count of the window's events; ON blue, OFF
  red, on a dark background, brighter with more events (saturating at :data:`SATURATE` events);
- gradient streams: per pixel, the net upward steps of each axis; X in the red channel, Y in the
  green, above mid-grey for upward steps and below it for downward ones.

``.png`` writes a strip of up to :data:`STRIP_ROWS` windows (one under the other); ``.gif`` an
animation of every window at ``fps``; ``.mp4`` the same through imageio's ffmpeg plugin
(``imageio-ffmpeg``), refused with a clear message where it is not installed.
"""

from __future__ import annotations

import importlib.util
import os
from pathlib import Path

import numpy as np

from gevsim.errors import ConfigError, suggest
from gevsim.io.atomic import atomic_path
from gevsim.io.hdf5 import EventReader
from gevsim.io.ownership import check_file

__all__ = ["render_windows", "view"]

#: Events at a pixel at which its colour saturates.
SATURATE = 3
#: Height of the strip above each row of panels giving its time and the panels' names (px).
LABEL_PX = 22
#: Text height in that strip (px).
FONT_PX = 15
#: A panel is drawn at least this wide (px; sensor pixels repeated by a whole number, at most MAX_SCALE).
PANEL_MIN_PX = 300
MAX_SCALE = 16
#: Gap between panels and height of the time bar under them (px).
GAP_PX, BAR_PX = 4, 5
#: Windows in a PNG strip at most.
STRIP_ROWS = 8
#: What marks a picture as written by `gevsim view` (PNG Software text, GIF comment).
MARK = "gevsim view"
_ON, _OFF, _BACK = np.array([70, 140, 255]), np.array([255, 80, 60]), np.array([24, 24, 24])
_TEXT, _TIME, _STRIP = (230, 230, 230), (255, 200, 90), (40, 40, 40)


def _brightness_panel(ev: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    net = np.zeros(shape)
    np.add.at(net, (ev["y"], ev["x"]), np.where(ev["p"] > 0, 1.0, -1.0))
    level = np.clip(np.abs(net) / SATURATE, 0, 1)[..., None]
    colour = np.where((net > 0)[..., None], _ON, _OFF)
    return (_BACK + level * (colour - _BACK)).astype(np.uint8)


def _gradient_panel(ev: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    img = np.full((*shape, 3), 128.0)
    for axis in (0, 1):
        sel = ev[ev["axis"] == axis]
        net = np.zeros(shape)
        np.add.at(net, (sel["y"], sel["x"]), sel["p"].astype(float))
        img[..., axis] += 127 * np.clip(net / SATURATE, -1, 1)
    return img.astype(np.uint8)


def _truth_panel(frames: np.ndarray, t_us: np.ndarray, at_us: int, low: float, high: float) -> np.ndarray:
    k = int(np.clip(np.searchsorted(t_us, at_us, side="right") - 1, 0, len(frames) - 1))
    grey = np.clip((frames[k] - low) / max(high - low, 1e-12), 0, 1) * 255
    return np.repeat(grey[..., None], 3, axis=2).astype(np.uint8)


def _time_bar(width: int, start_us: int, end_us: int, total_us: int) -> np.ndarray:
    bar = np.full((BAR_PX, width, 3), 40, np.uint8)
    a, b = (int(round(width * v / max(total_us, 1))) for v in (start_us, end_us))
    bar[1:, a:max(b, a + 1)] = (230, 230, 230)
    return bar


def panel_scale(width: int) -> int:
    """Picture pixels per sensor pixel: the least whole number making a panel PANEL_MIN_PX wide (1 to MAX_SCALE)."""
    return int(min(MAX_SCALE, max(1, -(-PANEL_MIN_PX // max(width, 1)))))


def window_label(start_us: int, end_us: int) -> str:
    """A window's time as a strip shows it: ``18.00-18.25 ms`` (three decimals where a limit is not a whole
    10 us)."""
    digits = 3 if start_us % 10 or end_us % 10 else 2
    return f"{start_us / 1000:.{digits}f}-{end_us / 1000:.{digits}f} ms"


def stream_title(stream: str) -> str:
    """A stream's human name (its emulator's label: DVS, gradient, gradient RC, CSDVS); others as they are."""
    from gevsim.emulation.emulators import EMULATORS

    return next((e.label for e in EMULATORS.values() if e.stream == stream), stream)


def _font(size: int):
    from PIL import ImageFont

    try:
        return ImageFont.load_default(size=size)  # Pillow >= 10.1 with FreeType: a scalable font
    except (TypeError, OSError, ImportError):  # pragma: no cover - older Pillow: the small bitmap font
        return ImageFont.load_default()


def header(time: str, names: list[str], panel_width: int, width: int) -> np.ndarray:
    """The strip above a row of panels: the window's time at the left, then each panel's name over it."""
    from PIL import Image, ImageDraw

    strip = Image.new("RGB", (width, LABEL_PX), _STRIP)
    draw = ImageDraw.Draw(strip)
    font = _font(FONT_PX)
    top = max(0, (LABEL_PX - FONT_PX) // 2 - 1)
    draw.text((4, top), time, fill=_TIME, font=font)
    after_time = 4 + int(draw.textlength(time, font=font)) + 14
    for i, name in enumerate(names):
        left = i * (panel_width + GAP_PX) + 4
        draw.text((max(left, after_time) if i == 0 else left, top), name, fill=_TEXT, font=font)
    return np.asarray(strip, np.uint8)


def _default_streams(streams: list[str]) -> list[str]:
    """Every stream, the emulators' own in their registry order (DVS, gradient, gradient RC, CSDVS) first."""
    from gevsim.emulation.emulators import EMULATORS

    known = [e.stream for e in EMULATORS.values() if e.stream in streams]
    return known + sorted(s for s in streams if s not in known)


def render_windows(path: str | os.PathLike, *, window_us: int = 1000, streams: list[str] | None = None,
                   start_us: int = 0, count: int | None = None) -> tuple[np.ndarray, list[str]]:
    """(N, height, width, 3) uint8 pictures of the windows ``[start + k window, start + (k + 1) window)``
    of an emulation file, and the panels' names (left to right: the streams, DVS first and then in the
    emulators' order, and ``ground truth``; each picture shows their human names, :func:`stream_title`)."""
    if window_us < 1:
        raise ConfigError(f"the window must be at least 1 us, got {window_us}", key="--window-ms")
    with EventReader(path) as r:
        names = _default_streams(list(r.streams)) if streams is None else streams
        for s in names:
            if s not in r.streams:
                raise ConfigError(f"no stream {s!r}{suggest(s, r.streams)}; streams: {', '.join(r.streams)}",
                                  source=str(path), key="--streams")
        shape, total = (r.height, r.width), r.t_end_us
        truth = r.frames("log_photocurrent") if "log_photocurrent" in r.frame_names else None
        n = max(1, (total - start_us + window_us - 1) // window_us)
        n = min(n, count) if count else n
        pictures = []
        titles = names + (["ground truth"] if truth is not None else [])
        shown = [stream_title(t) for t in titles]
        k = panel_scale(shape[1])
        low, high = (np.percentile(truth[0], [1, 99]) if truth is not None else (0.0, 1.0))
        for i in range(n):
            a, b = start_us + i * window_us, start_us + (i + 1) * window_us
            panels = []
            for s in names:
                ev = r.read(s, t_start_us=a, t_end_us=b)
                gradient = "axis" in (ev.dtype.names or ())
                panels.append(_gradient_panel(ev, shape) if gradient else _brightness_panel(ev, shape))
            if truth is not None:
                panels.append(_truth_panel(truth[0], truth[1], b, float(low), float(high)))
            gap = np.zeros((shape[0] * k, GAP_PX, 3), np.uint8)
            big = [p.repeat(k, axis=0).repeat(k, axis=1) for p in panels]
            row = np.concatenate([p for panel in big for p in (panel, gap)][:-1], axis=1)
            label = header(window_label(a, b), shown, shape[1] * k, row.shape[1])
            pictures.append(np.concatenate([label, row, _time_bar(row.shape[1], a, b, total)], axis=0))
    return np.asarray(pictures), titles


VIDEO_MIN_WIDTH = 640  # px: MP4 pictures are enlarged by whole pixels to at least this width (video_frames)


def view(path: str | os.PathLike, out: str | os.PathLike, *, window_us: int = 1000, streams: list[str] | None = None,
         fps: float = 10.0, start_us: int = 0) -> Path:
    """Write the event pictures of an emulation file (:func:`render_windows`) to ``out``: ``.png`` (a strip
    of up to STRIP_ROWS windows), ``.gif`` or ``.mp4`` (every window, ``fps`` a second)."""
    import imageio.v3 as iio

    out = Path(out)
    kind = out.suffix.lower()
    if kind not in (".png", ".gif", ".mp4"):
        raise ConfigError(f"unknown picture type {kind or '(none)'!r}; name a .png, .gif or .mp4 file", source=str(out))
    if kind == ".mp4" and importlib.util.find_spec("imageio_ffmpeg") is None:
        raise ConfigError("writing .mp4 needs imageio's ffmpeg plugin: pip install imageio-ffmpeg (or write a .gif)",
                          source=str(out))
    if not fps > 0:
        raise ConfigError(f"fps must be > 0, got {fps}", key="--fps")
    check_file(out, "picture", _is_ours, inputs=[path])  # replaces only an earlier `gevsim view` picture
    pictures, _ = render_windows(path, window_us=window_us, streams=streams, start_us=start_us,
                                 count=STRIP_ROWS if kind == ".png" else None)
    from PIL import Image, PngImagePlugin

    with atomic_path(out) as tmp:
        if kind == ".png":
            info = PngImagePlugin.PngInfo()
            info.add_text("Software", MARK)
            Image.fromarray(np.concatenate(list(pictures), axis=0)).save(tmp, format="PNG", pnginfo=info)
        elif kind == ".gif":
            frames = [Image.fromarray(p) for p in pictures]
            frames[0].save(tmp, format="GIF", save_all=True, append_images=frames[1:], duration=1000.0 / fps,
                           loop=0, comment=MARK.encode())
        else:
            video, _ = video_frames(pictures)
            iio.imwrite(tmp, video, extension=".mp4", fps=fps, macro_block_size=1,
                        output_params=["-metadata", f"comment={MARK}"])
    return out


def video_frames(pictures: np.ndarray) -> tuple[np.ndarray, int]:
    """The pictures as an H.264 encoder takes them without blurring single-pixel events: each picture
    pixel repeated ``k`` x ``k`` times (the least ``k`` <= 8 making them VIDEO_MIN_WIDTH wide; 4:2:0
    chroma then never mixes two pixels' colours), padded at the right and bottom to a multiple of 16
    (the encoder's macroblock; it would otherwise rescale). Returns the frames and ``k``."""
    n, h, w, _ = pictures.shape
    k = int(min(8, max(1, -(-VIDEO_MIN_WIDTH // w))))
    big = pictures.repeat(k, axis=1).repeat(k, axis=2)
    frames = np.zeros((n, -(-h * k // 16) * 16, -(-w * k // 16) * 16, 3), np.uint8)
    frames[:, :h * k, :w * k] = big
    return frames, k


def _is_ours(path: Path) -> bool:
    """A picture `gevsim view` wrote (its Software text or comment names gevsim)."""
    if path.suffix.lower() == ".mp4":  # the comment atom sits near one end of the file
        with open(path, "rb") as fh:
            head = fh.read(65536)
            fh.seek(max(0, path.stat().st_size - 65536))
            return MARK.encode() in head + fh.read()
    try:
        from PIL import Image

        with Image.open(path) as img:
            tag = img.info.get("Software") or img.info.get("comment") or b""
    except Exception:
        return False
    return (tag.decode(errors="replace") if isinstance(tag, bytes) else str(tag)) == MARK
