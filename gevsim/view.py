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
(``imageio-ffmpeg``), refused with a clear message where it is not installed. Each window is written
as soon as it is drawn (:mod:`gevsim.view_writer`): memory holds one window, never the whole view;
more than :data:`MAX_FRAMES` windows, and times or rates out of range, are refused before any work.
"""

from __future__ import annotations

import functools
import importlib.util
import math
import os
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from gevsim.errors import ConfigError, suggest
from gevsim.io.atomic import atomic_path
from gevsim.io.checks import MAX_T_END_US
from gevsim.io.hdf5 import EventReader
from gevsim.io.ownership import check_file
from gevsim.view_writer import MARK, VIDEO_MIN_WIDTH, abandon, check_fps, is_ours, open_writer, video_frames

__all__ = ["MARK", "MAX_FRAMES", "VIDEO_MIN_WIDTH", "ms_to_us", "render_windows", "video_frames", "view",
           "window_count"]

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
#: Windows one view draws at most, unless ``max_frames`` (``--max-frames``) says more: 10,000 frames are
#: 17 minutes of animation at the default 10 fps and some minutes of drawing, more than anyone watches
#: window by window; a count past it is almost always the default 1 ms window left on a long file (a
#: day-long file is 86,400,000 of them, days of drawing), so it is refused before any work, naming
#: the flags that change it.
MAX_FRAMES = 10_000
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


@functools.lru_cache(maxsize=4)
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


def ms_to_us(value: object, flag: str) -> int:
    """A command-line time in ms (``--window-ms``, ``--start-ms``, ``--end-ms``) as whole microseconds; one
    that is not a finite number from 0 to a day (the longest recording, :data:`MAX_T_END_US`) is a
    :class:`ConfigError` naming ``flag``."""
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating) \
            or not math.isfinite(value) or not 0 <= value <= MAX_T_END_US / 1000:
        shown = f"{value:g}" if isinstance(value, float | np.floating) else repr(value)
        raise ConfigError(f"must be a finite number of ms from 0 to {_ms(MAX_T_END_US)} (a day), got {shown}", key=flag)
    return int(round(float(value) * 1000))


def _check_times(window_us: object, start_us: object, end_us: object, max_frames: object) -> None:
    """The windows' integer arguments, before any work (the keys name the command's flags)."""
    for value, flag, low in ((window_us, "--window-ms", 1), (start_us, "--start-ms", 0), (end_us, "--end-ms", 0),
                             (max_frames, "--max-frames", 1)):
        if value is None and flag == "--end-ms":
            continue
        if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < low:
            wanted = "a whole number of frames >= 1" if flag == "--max-frames" else \
                f"a whole number of us >= {low}" + (" (0.001 ms)" if low else "")
            raise ConfigError(f"must be {wanted}, got {value!r}", key=flag)
        if flag != "--max-frames" and value > MAX_T_END_US:
            raise ConfigError(f"must be at most a day ({MAX_T_END_US} us), got {value!r} us", key=flag)


def _ms(us: int) -> str:
    """Microseconds as ms for a message: ``86,400,000``, ``0.25``."""
    return f"{us / 1000:,.3f}".rstrip("0").rstrip(".")


def window_count(total_us: int, *, window_us: int, start_us: int = 0, end_us: int | None = None,
                 max_frames: int | None = MAX_FRAMES, source: str | None = None) -> int:
    """How many windows ``[start + k window, start + (k + 1) window)`` cover ``[start_us, end_us)`` (``end_us``
    None: the file's end ``total_us``; at least one window); more than ``max_frames`` (None: no limit) is
    refused up front with a line saying how many and which flag to change."""
    end = total_us if end_us is None else end_us
    if end > total_us:
        raise ConfigError(f"{_ms(end)} ms is past the file's end ({_ms(total_us)} ms)", source=source,
                          key="--end-ms")
    if start_us >= end and (start_us > 0 or end_us is not None):
        raise ConfigError(f"{_ms(start_us)} ms is not before the end of the view ({_ms(end)} ms"
                          f"{', the end of the file' if end_us is None else ''})", source=source, key="--start-ms")
    n = max(1, -(-(end - start_us) // window_us))
    if max_frames is not None and n > max_frames:
        fit = -(-(end - start_us) // max_frames)
        raise ConfigError(f"{n:,} windows of {_ms(window_us)} ms from {_ms(start_us)} to {_ms(end)} ms are more than "
                          f"the {max_frames:,} frames a view draws at most: give a longer --window-ms (at least "
                          f"{_ms(fit)}), a shorter span (--start-ms, --end-ms) or a larger --max-frames", source=source)
    return n


def _pictures(r: EventReader, names: list[str], *, window_us: int, start_us: int, n: int) -> Iterator[np.ndarray]:
    """The pictures of ``n`` windows of the open file ``r``, one at a time (the caller writes each before the next
    is drawn)."""
    shape, total = (r.height, r.width), r.t_end_us
    truth = r.frames("log_photocurrent") if "log_photocurrent" in r.frame_names else None
    shown = [stream_title(t) for t in names + (["ground truth"] if truth is not None else [])]
    k = panel_scale(shape[1])
    low, high = (np.percentile(truth[0], [1, 99]) if truth is not None else (0.0, 1.0))
    gap = np.zeros((shape[0] * k, GAP_PX, 3), np.uint8)
    for i in range(n):
        a, b = start_us + i * window_us, start_us + (i + 1) * window_us
        panels = []
        for s in names:
            ev = r.read(s, t_start_us=a, t_end_us=b)
            gradient = "axis" in (ev.dtype.names or ())
            panels.append(_gradient_panel(ev, shape) if gradient else _brightness_panel(ev, shape))
        if truth is not None:
            panels.append(_truth_panel(truth[0], truth[1], b, float(low), float(high)))
        big = [p.repeat(k, axis=0).repeat(k, axis=1) for p in panels]
        row = np.concatenate([p for panel in big for p in (panel, gap)][:-1], axis=1)
        label = header(window_label(a, b), shown, shape[1] * k, row.shape[1])
        yield np.concatenate([label, row, _time_bar(row.shape[1], a, b, total)], axis=0)


def _stream_names(r: EventReader, streams: list[str] | None, source: str) -> list[str]:
    names = _default_streams(list(r.streams)) if streams is None else streams
    for s in names:
        if s not in r.streams:
            raise ConfigError(f"no stream {s!r}{suggest(s, r.streams)}; streams: {', '.join(r.streams)}",
                              source=source, key="--streams")
    return names


def render_windows(path: str | os.PathLike, *, window_us: int = 1000, streams: list[str] | None = None,
                   start_us: int = 0, count: int | None = None) -> tuple[np.ndarray, list[str]]:
    """(N, height, width, 3) uint8 pictures of the windows ``[start + k window, start + (k + 1) window)``
    of an emulation file (``count`` of them, or up to the file's end: at most :data:`MAX_FRAMES`), and the
    panels' names (left to right: the streams, DVS first and then in the emulators' order, and
    ``ground truth``; each picture shows their human names, :func:`stream_title`). Holds every picture:
    :func:`view` writes them one at a time instead."""
    _check_times(window_us, start_us, None, MAX_FRAMES)
    with EventReader(path) as r:
        n = window_count(r.t_end_us, window_us=window_us, start_us=start_us, source=str(path),
                         max_frames=None if count else MAX_FRAMES)
        n = min(n, count) if count else n
        names = _stream_names(r, streams, str(path))
        titles = names + (["ground truth"] if "log_photocurrent" in r.frame_names else [])
        return np.asarray(list(_pictures(r, names, window_us=window_us, start_us=start_us, n=n))), titles


def view(path: str | os.PathLike, out: str | os.PathLike, *, window_us: int = 1000, streams: list[str] | None = None,
         fps: float = 10.0, start_us: int = 0, end_us: int | None = None, max_frames: int = MAX_FRAMES) -> Path:
    """Write the event pictures of an emulation file's windows ``[start + k window, start + (k + 1) window)``
    from ``start_us`` to ``end_us`` (None: the file's end) to ``out``: ``.png`` (a strip of the first
    STRIP_ROWS windows), ``.gif`` or ``.mp4`` (every window, ``fps`` a second), each window written as it is
    drawn (memory: one window and the encoder). An animation of more than ``max_frames`` windows is refused
    before any work (see :data:`MAX_FRAMES`; a strip draws its STRIP_ROWS whatever the span), as are times,
    counts and rates out of range (:class:`ConfigError` naming the command's flag)."""
    out = Path(out)
    kind = out.suffix.lower()
    if kind not in (".png", ".gif", ".mp4"):
        raise ConfigError(f"unknown picture type {kind or '(none)'!r}; name a .png, .gif or .mp4 file", source=str(out))
    if kind == ".mp4" and importlib.util.find_spec("imageio_ffmpeg") is None:
        raise ConfigError("writing .mp4 needs imageio's ffmpeg plugin: pip install imageio-ffmpeg (or write a .gif)",
                          source=str(out))
    fps = check_fps(fps, kind)
    _check_times(window_us, start_us, end_us, max_frames)
    check_file(out, "picture", is_ours, inputs=[path])  # replaces only an earlier `gevsim view` picture
    with EventReader(path) as r:
        n = window_count(r.t_end_us, window_us=window_us, start_us=start_us, end_us=end_us, source=str(path),
                         max_frames=None if kind == ".png" else max_frames)
        names = _stream_names(r, streams, str(path))
        with atomic_path(out) as tmp:
            writer = open_writer(tmp, kind, fps)
            try:
                for picture in _pictures(r, names, window_us=window_us, start_us=start_us,
                                         n=min(n, STRIP_ROWS) if kind == ".png" else n):
                    writer.append(picture)
            except BaseException:
                abandon(writer)
                raise
            writer.close()
    return out
