"""Frame sequences for frame mode: users' frame folders, videos and EVREAL sequence
folders read into (N, H, W) float64 gray frames in [0, 1] and times in seconds
(:func:`gevsim.emulation.run_frames` turns them into events)."""

from __future__ import annotations

import logging
import math
import os
import re
from pathlib import Path

import numpy as np

from gevsim import _resources
from gevsim._portable import combine
from gevsim._validate import FieldError, increasing, real
from gevsim.errors import ConfigError, MissingExtraError, one_line
from gevsim.io.evreal import import_evreal
from gevsim.resources import FRAME_PX_BYTES, check_frame_memory, fits_memory
from gevsim.timebase import MAX_DURATION_S

log = logging.getLogger(__name__)

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".tif", ".tiff")
TIMESTAMPS_FILE = "timestamps.txt"
#: Rec.601 luma weights (ITU-R BT.601; OpenCV's and Pillow's RGB -> gray). Note that
#: skimage.color.rgb2gray uses the Rec.709 weights 0.2125, 0.7154, 0.0721 instead.
REC601_LUMA = (0.299, 0.587, 0.114)


def _imread(path: Path) -> np.ndarray:
    try:
        import imageio.v3 as iio
    except ImportError:  # scikit-image reads through imageio too, but try it anyway
        from skimage.io import imread
        return np.asarray(imread(path))
    return np.asarray(iio.imread(path))


def _to_gray(img: np.ndarray, *, channels: bool, source: str) -> np.ndarray:
    """Integer images scaled by their dtype's maximum (8- and 16-bit alike), float images
    taken as they are (must lie in [0, 1]); colour to gray by Rec.601 luma; alpha dropped.

    A pixel whose R, G and B are equal (a gray RGB or palette image) keeps that value exactly:
    the float sum ``0.299 v + 0.587 v + 0.114 v`` can be an ulp off ``v``, and the paper's gradient
    thresholds (4, 8, 16 / 255) sit exactly on code steps, so an ulp would flip comparators (issue 36:
    324 gradient events from a gray RGB picture, 216 from the same picture saved as L)."""
    if img.dtype == np.bool_:
        img = img.astype(np.float64)
    elif img.dtype.kind == "u":
        img = img.astype(np.float64) / np.iinfo(img.dtype).max
    elif img.dtype.kind == "f":
        img = img.astype(np.float64)
        if not np.all(np.isfinite(img)) or img.min(initial=0.0) < 0 or img.max(initial=0.0) > 1:
            raise ConfigError("float images must be finite and within [0, 1]", source=source)
    else:
        raise ConfigError(f"unsupported pixel type {img.dtype}", source=source)
    if channels:
        c = img.shape[-1]
        if c in (1, 2):  # gray, gray + alpha
            img = img[..., 0]
        elif c in (3, 4):  # RGB, RGBA
            r, g, b = img[..., 0], img[..., 1], img[..., 2]
            img = np.where((r == g) & (g == b), r, combine(img[..., :3], REC601_LUMA))
        else:
            raise ConfigError(f"cannot make a grayscale image of {c} channels", source=source)
    return img


def _natural_key(name: str):
    return tuple(int(s) if i % 2 else s for i, s in enumerate(re.split(r"(\d+)", name)))


def _check_times(t: np.ndarray, n: int, *, source: str) -> np.ndarray:
    if len(t) != n:
        raise ConfigError(f"{len(t)} timestamps for {n} frames", source=source)
    try:
        return _in_range(increasing(t, "timestamps", what="entry"), source=source)
    except FieldError as err:
        raise ConfigError(str(err), source=source) from None


#: The latest frame time: the longest recording an event file holds (a day).
_LATEST_S = MAX_DURATION_S


def _in_range(t: np.ndarray, *, source: str, key: str | None = None) -> np.ndarray:
    """Frame times must be >= 0 and fit an event file's int64 microsecond clock."""
    if len(t) and t[0] < 0:
        raise ConfigError(f"times must be >= 0 s, got {t[0]!r}", source=source, key=key)
    if len(t) and not t[-1] < _LATEST_S:
        raise ConfigError(f"frame {len(t) - 1} is at {t[-1]:.4g} s, past the latest time an event file holds "
                          f"({_LATEST_S:.4g} s)", source=source, key=key)
    same = np.flatnonzero(np.diff(np.round(t * 1e6)) <= 0)  # frame times are stored in whole microseconds
    if same.size:
        k = int(same[0])
        raise ConfigError(f"frames {k} and {k + 1} ({t[k]!r} s, {t[k + 1]!r} s) fall on the same microsecond, the "
                          "clock tick of event files: frames must be at least 1 us apart", source=source, key=key)
    return t


def _fps_times(fps, n: int, *, source: str) -> np.ndarray:
    try:
        return _in_range(np.arange(n) / real(fps, "fps", low=0.0, low_open=True), source=source, key="fps")
    except FieldError as err:
        raise ConfigError(str(err), source=source, key="fps") from None


def _read_timestamps(path: Path) -> np.ndarray:
    values = []
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise ConfigError(f"not UTF-8 text: byte {exc.start} is 0x{exc.object[exc.start]:02x} (expected one time "
                          "in seconds per line)", source=str(path)) from None
    except OSError as exc:
        raise ConfigError(f"cannot read the timestamps: {exc.strerror or exc}", source=str(path)) from None
    for i, line in enumerate(text.splitlines(), start=1):
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        try:
            values.append(float(line))
        except ValueError:
            raise ConfigError(f"expected one time in seconds per line, got {line!r}", source=str(path),
                              key=f"line {i}") from None
    return np.asarray(values, dtype=np.float64)


def load_frame_folder(folder: str | os.PathLike, *, fps: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Read the PNG/JPEG/TIFF frames of a folder, in natural name order (frame2 before frame10).

    Timestamps come from ``timestamps.txt`` in the folder: one time in seconds per line,
    one line per frame in the same order (blank lines and lines starting with ``#`` are
    skipped); it takes precedence over ``fps``. Without it, frame k is at ``k / fps``.

    Returns
    -------
    frames : float64 (N, H, W) in [0, 1]; 8- and 16-bit images scaled by 255 and 65535,
        colour converted to gray with Rec.601 luma.
    t_s : float64 (N,), seconds.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise ConfigError("not a folder", source=str(folder))
    files = sorted((p for p in folder.iterdir() if p.is_file() and not p.name.startswith(".")
                    and p.suffix.lower() in IMAGE_SUFFIXES), key=lambda p: _natural_key(p.name))
    if not files:
        raise ConfigError(f"no image files ({', '.join(IMAGE_SUFFIXES)}) in the folder", source=str(folder))
    frames = np.empty((0, 0, 0))
    for k, path in enumerate(files):
        try:
            img = _imread(path)
        except Exception as exc:  # imageio raises plugin-specific errors
            raise ConfigError(f"cannot read the image ({one_line(exc)})", source=str(path)) from None
        img = _to_gray(img, channels=img.ndim == 3, source=str(path))
        if img.ndim != 2:
            raise ConfigError(f"expected one 2-D image, got shape {img.shape}", source=str(path))
        if k == 0:  # the whole sequence's memory, before the other frames are read, then one array for all
            check_frame_memory(len(files), img.shape, source=str(folder))
            frames = np.empty((len(files), *img.shape))
        elif img.shape != frames.shape[1:]:
            raise ConfigError(f"frame shape {img.shape} differs from {frames.shape[1:]} of {files[0].name}",
                              source=str(path))
        frames[k] = img
    ts_path = folder / TIMESTAMPS_FILE
    if ts_path.is_file():
        if fps is not None:
            log.warning("%s: using %s, ignoring fps=%r", folder, TIMESTAMPS_FILE, fps)
        t = _check_times(_read_timestamps(ts_path), len(files), source=str(ts_path))
    elif fps is None:
        raise ConfigError(f"no {TIMESTAMPS_FILE} in the folder: give fps", source=str(folder))
    else:
        t = _fps_times(fps, len(files), source=str(folder))
    return frames, t


def load_video(path: str | os.PathLike, *, fps: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Read a video (any format imageio can read; MP4/AVI need its pyav or ffmpeg plugin)
    into grayscale frames in [0, 1] and times ``k / fps``, with ``fps`` taken from the
    video's metadata unless given.

    The frames are decoded one at a time into one float64 (N, H, W) array. Before any frame is
    decoded, the frame count the container states (``nframes``, or ``duration`` x ``fps``) times
    the frame size is checked against memory (:func:`~gevsim.resources.check_frame_memory`); where
    the count is not stated, decoding stops with a :class:`~gevsim.errors.ConfigError` as soon as the
    frames read so far pass that budget.
    """
    try:
        import imageio.v3 as iio
    except ImportError:
        raise MissingExtraError("load_video needs imageio: pip install 'imageio[pyav]'") from None
    path = Path(path)
    if not path.is_file():
        raise ConfigError("no such file", source=str(path))
    try:
        with iio.imopen(path, "r", legacy_mode=True) as file:
            meta = dict(file.metadata())
            frames = _decode(file.iter(), _stated_count(meta), _stated_shape(meta), source=str(path))
    except ConfigError:
        raise
    except Exception as exc:  # imageio's plugins raise their own errors
        raise ConfigError(f"cannot read the video ({one_line(exc)}); MP4/AVI need imageio's pyav or ffmpeg plugin",
                          source=str(path)) from None
    if fps is None:
        fps = meta.get("fps")
        if _positive(fps) is None:
            stated = "has no frame rate" if fps is None else f"states a frame rate of {fps!r}"
            raise ConfigError(f"the video's metadata {stated}: give fps", source=str(path), key="fps")
    return frames, _fps_times(fps, len(frames), source=str(path))


def _positive(value) -> float | None:
    """``value`` as a float when it is a finite positive number (metadata can hold anything), else None."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
        return None
    x = float(value)
    return x if math.isfinite(x) and x > 0 else None


def _stated_count(meta: dict) -> int | None:
    """The frame count a container states: ``nframes``, else ``duration`` (s) x ``fps``; None if neither."""
    n = _positive(meta.get("nframes"))
    if n is None:
        duration, fps = _positive(meta.get("duration")), _positive(meta.get("fps"))
        n = None if duration is None or fps is None else _positive(duration * fps)  # None where it overflows
    return None if n is None else max(1, math.ceil(n - 1e-6))


def _stated_shape(meta: dict) -> tuple[int, int] | None:
    """(H, W) from ffmpeg's ``size`` (W, H), None where it is not stated."""
    size = meta.get("size")
    if not isinstance(size, (tuple, list)) or len(size) != 2:
        return None
    w, h = (_positive(v) for v in size)
    return None if w is None or h is None else (int(h), int(w))


def _decode(images, count: int | None, shape: tuple[int, int] | None, *, source: str) -> np.ndarray:
    """Gray frames from an iterator of images into one preallocated float64 array of the stated ``count``
    (grown by doubling when the video holds more frames, or states none), memory checked before the first
    frame is decoded (from the header's ``count`` and ``shape``) and as the array grows."""
    if count is not None and shape is not None:  # all from the container's header: nothing decoded yet
        _check_stated(count, shape, source=source)
    out = np.empty((0, 0, 0))
    k = 0
    for img in images:
        img = np.asarray(img)
        gray = _to_gray(img, channels=img.ndim == 3, source=source)
        if gray.ndim != 2:
            raise ConfigError(f"expected (N, H, W[, C]) frames, got a frame of shape {img.shape}", source=source)
        if k == 0 and count is not None:
            _check_stated(count, gray.shape, source=source)  # the size may differ from the header's
            out = np.empty((count, *gray.shape))
        elif k == 0 or k == len(out):
            out = _grow(out, k, gray.shape, source=source)
        elif gray.shape != out.shape[1:]:
            raise ConfigError(f"frame {k} has shape {gray.shape}, frame 0 {out.shape[1:]}", source=source)
        out[k] = gray
        k += 1
    if k == 0:
        raise ConfigError("the video holds no frames", source=source)
    return out[:k]


def _check_stated(count: int, shape: tuple[int, ...], *, source: str) -> None:
    h, w = shape
    fits_memory(count * h * w * FRAME_PX_BYTES, what=f"the {count} frames of {w}x{h} px its metadata states",
                source=source, key=None, hint=": use a shorter or smaller video")


def _grow(frames: np.ndarray, k: int, shape: tuple[int, ...], *, source: str) -> np.ndarray:
    """``frames[:k]`` in a new array of twice as many frames (8 at first), as many as fit the memory budget
    of :func:`~gevsim.resources.check_frame_memory`; past it, decoding stops with a ConfigError."""
    if k and shape != frames.shape[1:]:
        raise ConfigError(f"frame {k} has shape {shape}, frame 0 {frames.shape[1:]}", source=source)
    h, w = shape
    have, _ = _resources.usable_memory()
    capacity = max(8, 2 * k) if have is None else min(max(8, 2 * k), have // (h * w * FRAME_PX_BYTES))
    if capacity <= k:  # the frames read so far and this one pass the budget
        fits_memory((k + 1) * h * w * FRAME_PX_BYTES, what=f"the first {k + 1} frames of {w}x{h} px (decoding "
                    "stopped there; the video's metadata states no frame count)", source=source, key=None,
                    hint=": use a shorter or smaller video")
        capacity = k + 1  # fits_memory and the budget disagree only by rounding
    out = np.empty((capacity, *shape))
    if k:
        out[:k] = frames[:k]
    return out


def load_evreal_frames(folder: str | os.PathLike) -> tuple[np.ndarray, np.ndarray]:
    """The ground-truth frames of an EVREAL sequence folder: (images / 255, images_ts in s)."""
    _, images, images_t_us, _, _ = import_evreal(folder)
    if images is None or images_t_us is None or len(images) == 0:
        raise ConfigError("the EVREAL sequence has no ground-truth images (images.npy)", source=str(folder))
    return images.astype(np.float64) / 255.0, images_t_us.astype(np.float64) / 1e6
