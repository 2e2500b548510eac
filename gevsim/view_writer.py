"""Where ``gevsim view``'s pictures go: a PNG strip, or a GIF or MP4 animation written one window at a time.

The animations stream: each picture is encoded and written (GIF) or piped to ffmpeg (MP4) as it is
drawn, so a view holds one window's picture (and the encoder's own buffers: ffmpeg's few frames of
look-ahead) whatever the number of windows. Pillow's and imageio's animation writers keep every frame
until they close, which made a long file's view grow without bound (issue 36). A PNG strip holds its
:data:`gevsim.view.STRIP_ROWS` windows, at most eight.

Frame rates (``fps``) are checked against what each format can store: a GIF gives each frame a delay of
a whole number of hundredths of a second, 1 to 65535 (so at most 100 frames a second; the rate is
rounded to the nearest such delay); an MP4 through ffmpeg is limited here to :data:`MP4_FPS` (ffmpeg's
MP4 muxer refuses frames lasting days, such as ``--fps 1e-6``; past 1000 frames a second players drop
frames).
"""

from __future__ import annotations

import importlib.util
import math
from collections.abc import Generator
from pathlib import Path
from typing import IO, Any

import numpy as np

from gevsim.errors import ConfigError

__all__ = ["MARK", "VIDEO_MIN_WIDTH", "Writer", "abandon", "check_fps", "is_ours", "open_writer", "video_frames"]

#: What marks a picture as written by `gevsim view` (PNG Software text, GIF comment, MP4 comment).
MARK = "gevsim view"
#: Frames a second a GIF can store: a delay of 1 to 65535 hundredths of a second (GIF89a's Graphic Control
#: Extension); an MP4 (see the module's notes).
GIF_FPS = (0.01, 100.0)
MP4_FPS = (0.01, 1000.0)
VIDEO_MIN_WIDTH = 640  # px: MP4 pictures are enlarged by whole pixels to at least this width (video_frames)


def check_fps(fps: object, kind: str) -> float:
    """``fps`` as a float, or a :class:`ConfigError` naming ``--fps``: a finite number > 0, and within what
    the format ``kind`` (``.png``, ``.gif``, ``.mp4``) can store (a PNG strip does not use it)."""
    if isinstance(fps, bool) or not isinstance(fps, int | float | np.integer | np.floating) \
            or not math.isfinite(fps) or fps <= 0:
        shown = f"{fps:g}" if isinstance(fps, float | np.floating) else repr(fps)
        raise ConfigError(f"must be a finite number of frames a second > 0, got {shown}", key="--fps")
    low, high = {".gif": GIF_FPS, ".mp4": MP4_FPS}.get(kind, (0.0, math.inf))
    if not low <= fps <= high:
        why = ("a GIF shows each frame a whole number of 1/100 s" if kind == ".gif"
               else "an MP4 frame lasts at most 100 s and players drop frames past 1000 a second")
        raise ConfigError(f"{why}: give {low:g} to {high:g} frames a second for a {kind}, got {fps:g}",
                          key="--fps")
    return float(fps)


class Writer:
    """Takes a view's pictures one at a time (:meth:`append`) and finishes the file (:meth:`close`)."""

    def append(self, picture: np.ndarray) -> None:
        raise NotImplementedError

    def close(self) -> None:
        raise NotImplementedError


class _PngStrip(Writer):
    """The windows one under the other in one PNG (at most STRIP_ROWS of them: the caller stops there)."""

    def __init__(self, path: Path):
        self.path, self.rows = path, []  # type: tuple[Path, list[np.ndarray]]

    def append(self, picture: np.ndarray) -> None:
        self.rows.append(picture)

    def close(self) -> None:
        from PIL import Image, PngImagePlugin

        info = PngImagePlugin.PngInfo()
        info.add_text("Software", MARK)
        Image.fromarray(np.concatenate(self.rows, axis=0)).save(self.path, format="PNG", pnginfo=info)


def gif_delay_ms(fps: float) -> int:
    """A GIF frame's delay at ``fps``: whole hundredths of a second, as GIF stores them (30 fps plays at 33.3)."""
    return 10 * max(1, round(100 / fps))


class _GifStream(Writer):
    """An endless-loop GIF written frame by frame, as Pillow's GIF writer makes it but without holding the
    frames: the first picture whole (its median-cut palette of at most 256 colours the global colour
    table), each later one as the box around what changed since the one before, its unchanged pixels
    transparent (they compress to almost nothing), with its own palette. Holds the previous picture."""

    def __init__(self, fh: IO[bytes], fps: float):
        self.fh = fh
        self.delay_ms = gif_delay_ms(fps)
        self.previous: np.ndarray | None = None

    def append(self, picture: np.ndarray) -> None:
        from PIL import GifImagePlugin, Image

        params: dict[str, Any] = {"duration": self.delay_ms, "disposal": 1}  # 1: later frames draw over it
        if self.previous is None:
            image = Image.fromarray(picture).convert("P", palette=Image.Palette.ADAPTIVE)
            head, _ = GifImagePlugin.getheader(image, info={"loop": 0, "comment": MARK.encode(), **params})
            self.fh.write(b"".join(head))
            offset = (0, 0)
        else:
            changed = (picture != self.previous).any(axis=2)
            rows, cols = np.flatnonzero(changed.any(axis=1)), np.flatnonzero(changed.any(axis=0))
            if not rows.size:  # the same picture again: one pixel drawn over itself
                rows, cols = np.zeros(1, int), np.zeros(1, int)
            box = np.s_[rows[0]:rows[-1] + 1, cols[0]:cols[-1] + 1]
            image = Image.fromarray(picture[box]).convert("P", palette=Image.Palette.ADAPTIVE, colors=255)
            index = np.asarray(image).copy()
            index[~changed[box]] = 255  # the one index the 255 colours leave free: transparent
            palette = image.getpalette() or []
            image = Image.fromarray(index, "P")
            image.putpalette(palette[:765] + [0] * (768 - len(palette[:765])))
            params.update(include_color_table=True, transparency=255)
            offset = (int(cols[0]), int(rows[0]))
        for chunk in GifImagePlugin.getdata(image, offset, **params):
            self.fh.write(chunk)
        self.previous = picture

    def close(self) -> None:
        self.fh.write(b";")  # the GIF trailer
        self.fh.close()


class _Mp4Stream(Writer):
    """H.264 through imageio-ffmpeg's pipe: each picture enlarged and padded (:func:`video_frames`) and
    sent to ffmpeg as it comes."""

    def __init__(self, path: Path, fps: float):
        self.path, self.fps = path, fps
        self.pipe: Generator[None, np.ndarray | None, None] | None = None

    def append(self, picture: np.ndarray) -> None:
        frame, _ = video_frames(picture)
        if self.pipe is None:
            import imageio_ffmpeg  # type: ignore[import-untyped]

            self.pipe = imageio_ffmpeg.write_frames(
                str(self.path), (frame.shape[1], frame.shape[0]), fps=self.fps, macro_block_size=1,
                output_params=["-metadata", f"comment={MARK}", "-f", "mp4"])
            self.pipe.send(None)  # starts ffmpeg
        self.pipe.send(np.ascontiguousarray(frame))

    def close(self) -> None:
        if self.pipe is not None:
            self.pipe.close()  # ends the input, waits for ffmpeg to finish the file


def open_writer(path: Path, kind: str, fps: float) -> Writer:
    """The writer of a ``.png``, ``.gif`` or ``.mp4`` view into ``path`` (a stage; the caller renames it)."""
    if kind == ".png":
        return _PngStrip(path)
    if kind == ".gif":
        return _GifStream(open(path, "wb"), fps)  # noqa: SIM115 (closed by close(), or by the caller on failure)
    if importlib.util.find_spec("imageio_ffmpeg") is None:  # pragma: no cover - checked before any work
        raise ConfigError("writing .mp4 needs imageio's ffmpeg plugin: pip install imageio-ffmpeg (or write a .gif)",
                          source=str(path))
    return _Mp4Stream(path, fps)


def abandon(writer: Writer) -> None:
    """Release what a writer holds after a failure (its stage is removed by the caller)."""
    if isinstance(writer, _GifStream):
        writer.fh.close()
    elif isinstance(writer, _Mp4Stream) and writer.pipe is not None:
        writer.pipe.close()  # imageio-ffmpeg ends ffmpeg


def video_frames(pictures: np.ndarray) -> tuple[np.ndarray, int]:
    """Pictures (``(..., h, w, 3)``: one or a batch) as an H.264 encoder takes them without blurring
    single-pixel events: each picture pixel repeated ``k`` x ``k`` times (the least ``k`` <= 8 making them
    VIDEO_MIN_WIDTH wide; 4:2:0 chroma then never mixes two pixels' colours), padded at the right and
    bottom to a multiple of 16 (the encoder's macroblock; it would otherwise rescale). Returns the frames
    and ``k``."""
    h, w = pictures.shape[-3:-1]
    k = int(min(8, max(1, -(-VIDEO_MIN_WIDTH // w))))
    big = pictures.repeat(k, axis=-3).repeat(k, axis=-2)
    frames = np.zeros((*pictures.shape[:-3], -(-h * k // 16) * 16, -(-w * k // 16) * 16, 3), np.uint8)
    frames[..., :h * k, :w * k, :] = big
    return frames, k


def is_ours(path: Path) -> bool:
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
