"""EVREAL sequence folders (Ercan et al., CVPRW 2023, github.com/ercanburak/EVREAL).

Conventions, taken from EVREAL's reader ``dataset.py`` (``MemMapDataset``) and its
converter ``tools/bag_to_npy.py``, which produced the benchmark's own ECD, MVSEC
and HQF folders:

``events_ts.npy``
    float64 (N,), seconds. gevsim writes ``t_us / 1e6`` without shifting the origin.
``events_xy.npy``
    int16 (N, 2), columns x, y.
``events_p.npy``
    uint8 (N,), 1 = ON, 0 = OFF; EVREAL maps it to +-1 with ``p * 2.0 - 1.0``.
``images.npy``
    uint8 (M, H, W, 1): EVREAL reads ``images[i][:, :, 0]``, so the trailing
    channel axis is required (bag_to_npy adds it with ``np.expand_dims``).
``images_ts.npy``
    float64 (M, 1), seconds.
``image_event_indices.npy``
    int64 (M, 1): ``clip(searchsorted(events_ts, images_ts, 'right') - 1, 0, N - 1)``,
    the index of the last event at or before each image (as bag_to_npy computes
    it). EVREAL uses it as the exclusive end of the events before image ``i``.
``metadata.json``
    ``{"sensor_resolution": [H, W]}``, the only key EVREAL reads; gevsim adds
    ``width``, ``height``, ``gevsim_version`` and ``extra_metadata``.

The images files are optional in EVREAL (it then has no ground truth); all
three must be present or all absent. A sequence needs at least two events:
``MemMapDataset.load_data`` squeezes the event files and takes ``events_ts[0]`` and
``events_ts[-1]`` as the sequence's time span, which raises IndexError for no events
and for one (squeezed to a scalar), so :func:`export_evreal` refuses to write such a
folder (:class:`TooFewEventsError`).
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from gevsim import __version__
from gevsim.errors import ConfigError
from gevsim.events.types import BRIGHTNESS_DTYPE, check_events
from gevsim.io.atomic import atomic_dir

EVENT_FILES = ("events_ts.npy", "events_xy.npy", "events_p.npy")


#: Fewest events of a sequence EVREAL's loader reads (see the module docstring).
MIN_EVENTS = 2


class TooFewEventsError(ValueError):
    """An EVREAL sequence with fewer than MIN_EVENTS events: EVREAL cannot load it."""

IMAGE_FILES = ("images.npy", "images_ts.npy", "image_event_indices.npy")
METADATA = "metadata.json"


def image_event_indices(events_t_us: np.ndarray, images_t_us: np.ndarray) -> np.ndarray:
    """EVREAL's (M, 1) index of the last event at or before each image time."""
    idx = np.searchsorted(events_t_us, images_t_us, side="right") - 1
    return np.clip(idx, 0, max(len(events_t_us) - 1, 0)).astype(np.int64).reshape(-1, 1)


def _to_uint8(images: np.ndarray) -> np.ndarray:
    if images.dtype == np.uint8:
        return images
    if not np.issubdtype(images.dtype, np.floating):
        raise TypeError(f"images must be uint8 or float in [0, 1], got {images.dtype}")
    return np.rint(np.clip(images, 0.0, 1.0) * 255.0).astype(np.uint8)


def export_evreal(folder: str | os.PathLike, events: np.ndarray, images: np.ndarray | None,
                  images_t_us: np.ndarray | None, *, width: int, height: int,
                  extra_metadata: dict | None = None) -> Path:
    """Write an EVREAL sequence folder (atomically: staged, then renamed).

    Parameters
    ----------
    folder : str or PathLike
        The sequence folder; replaced if it exists.
    events : ndarray of BRIGHTNESS_DTYPE
        Time-sorted brightness events.
    images : ndarray or None
        Ground-truth frames, uint8 or float in [0, 1], (M, H, W) or (M, H, W, 1).
    images_t_us : ndarray or None
        (M,) frame times in microseconds, non-decreasing.
    width, height : int
        Sensor size in pixels.
    extra_metadata : dict, optional
        More keys for ``metadata.json``.

    Raises
    ------
    TooFewEventsError
        If ``events`` holds fewer than two events: EVREAL's loader cannot read such a folder, so
        none is written.
    """
    check_events(events)
    if events.dtype != BRIGHTNESS_DTYPE:
        raise TypeError(f"EVREAL holds brightness events only, got dtype {events.dtype}")
    if len(events) < MIN_EVENTS:
        raise TooFewEventsError(
            f"{folder}: not written: {len(events)} event{'s' * (len(events) != 1)}, and EVREAL cannot load a "
            f"sequence with fewer than {MIN_EVENTS} (its MemMapDataset squeezes events_ts.npy and reads "
            "events_ts[0] and events_ts[-1])")
    if len(events) and (events["x"].min() < 0 or events["x"].max() >= width
                        or events["y"].min() < 0 or events["y"].max() >= height):
        raise ValueError(f"event coordinates fall outside the {width}x{height} sensor")
    if (images is None) != (images_t_us is None):
        raise ValueError("give both images and images_t_us, or neither")
    if images is not None:
        images = _to_uint8(np.asarray(images))
        if images.ndim == 4 and images.shape[-1] == 1:
            images = images[..., 0]
        if images.ndim != 3 or images.shape[1:] != (height, width):
            raise ValueError(f"images must be (M, {height}, {width}), got shape {images.shape}")
        images_t_us = np.asarray(images_t_us, dtype=np.int64).reshape(-1)
        if len(images_t_us) != len(images):
            raise ValueError(f"{len(images)} images but {len(images_t_us)} image times")
        if np.any(np.diff(images_t_us) < 0):
            raise ValueError("images_t_us must be non-decreasing")
    metadata = {"sensor_resolution": [int(height), int(width)], "width": int(width), "height": int(height),
                "gevsim_version": __version__, **(extra_metadata or {})}
    folder = Path(folder)
    with atomic_dir(folder) as stage:
        save = lambda name, arr: np.save(stage / name, arr, allow_pickle=False)  # noqa: E731
        save("events_ts.npy", events["t"] / 1e6)
        save("events_xy.npy", np.stack([events["x"], events["y"]], axis=1).astype(np.int16))
        save("events_p.npy", events["p"].astype(np.uint8))
        if images is not None and images_t_us is not None:
            save("images.npy", images[..., None])
            save("images_ts.npy", (images_t_us / 1e6).reshape(-1, 1))
            save("image_event_indices.npy", image_event_indices(events["t"], images_t_us))
        (stage / METADATA).write_text(json.dumps(metadata, indent=1))
    return folder


def _load(folder: Path, name: str) -> np.ndarray:
    path = folder / name
    if not path.is_file():
        raise ConfigError("missing file of an EVREAL sequence", source=str(path))
    try:
        return np.load(path, allow_pickle=False)
    except (ValueError, OSError, EOFError) as exc:
        raise ConfigError(f"not a readable .npy file ({exc})", source=str(path)) from None


def _column(arr: np.ndarray, path: Path, what: str, n: int | None = None) -> np.ndarray:
    """Accept (K,) or (K, 1) as EVREAL does (it squeezes); check K == n."""
    if arr.ndim == 2 and arr.shape[1] == 1:
        arr = arr[:, 0]
    if arr.ndim != 1 or (n is not None and len(arr) != n):
        want = f"({n},) or ({n}, 1)" if n is not None else "(K,) or (K, 1)"
        raise ConfigError(f"{what} must have shape {want}, got {arr.shape}", source=str(path))
    return arr


def import_evreal(folder: str | os.PathLike) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None, int, int]:
    """Read an EVREAL sequence folder.

    Returns
    -------
    events : ndarray of BRIGHTNESS_DTYPE
    images : uint8 (M, H, W) or None
    images_t_us : int64 (M,) or None
    width, height : int
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise ConfigError("not a folder", source=str(folder))
    meta_path = folder / METADATA
    if not meta_path.is_file():
        raise ConfigError("missing file of an EVREAL sequence", source=str(meta_path))
    try:
        height, width = (int(v) for v in json.loads(meta_path.read_text())["sensor_resolution"])
    except (ValueError, KeyError, TypeError) as exc:
        raise ConfigError(f"needs 'sensor_resolution': [H, W] ({exc!r})", source=str(meta_path)) from None

    ts = _column(_load(folder, "events_ts.npy"), folder / "events_ts.npy", "event times")
    n = len(ts)
    xy = _load(folder, "events_xy.npy")
    if xy.shape != (n, 2):
        raise ConfigError(f"must have shape ({n}, 2) to match events_ts.npy, got {xy.shape}",
                          source=str(folder / "events_xy.npy"))
    p = _column(_load(folder, "events_p.npy"), folder / "events_p.npy", "polarities", n)
    events = np.empty(n, dtype=BRIGHTNESS_DTYPE)
    events["t"] = np.rint(np.asarray(ts, dtype=np.float64) * 1e6)
    if np.any(np.diff(events["t"]) < 0):
        raise ConfigError("event times must be non-decreasing", source=str(folder / "events_ts.npy"))
    if n and (xy[:, 0].min() < 0 or xy[:, 0].max() >= width or xy[:, 1].min() < 0 or xy[:, 1].max() >= height):
        raise ConfigError(f"coordinates fall outside the {width}x{height} sensor of {METADATA}",
                          source=str(folder / "events_xy.npy"))
    events["x"], events["y"], events["p"] = xy[:, 0], xy[:, 1], p > 0

    present = [(folder / f).is_file() for f in IMAGE_FILES]
    if not any(present):
        return events, None, None, width, height
    images = _load(folder, "images.npy")
    if images.ndim == 4 and images.shape[-1] == 1:
        images = images[..., 0]
    if images.ndim != 3 or images.shape[1:] != (height, width) or images.dtype != np.uint8:
        raise ConfigError(f"must be uint8 (M, {height}, {width}, 1), got {images.dtype} {images.shape}",
                          source=str(folder / "images.npy"))
    m = len(images)
    images_ts = _column(_load(folder, "images_ts.npy"), folder / "images_ts.npy", "image times", m)
    idx = _column(_load(folder, "image_event_indices.npy"), folder / "image_event_indices.npy", "indices", m)
    if m and (idx.min() < 0 or idx.max() > max(n - 1, 0) or np.any(np.diff(idx) < 0)):
        raise ConfigError(f"indices must be non-decreasing and within [0, {max(n - 1, 0)}]",
                          source=str(folder / "image_event_indices.npy"))
    return events, images, np.rint(np.asarray(images_ts, np.float64) * 1e6).astype(np.int64), width, height


def export_evreal_from(path: str | os.PathLike, folder: str | os.PathLike, *, extra_metadata: dict | None = None
                       ) -> dict:
    """An emulation file's DVS stream and its ground truth (``/frames/log_photocurrent``, tone-mapped to
    uint8 by :class:`~gevsim.tonemap.ToneMap` from the frames' own range) as an EVREAL sequence
    folder; returns ``{"events": count}``. Refuses a file with fewer than :data:`MIN_EVENTS` DVS events
    (EVREAL cannot load it)."""
    from gevsim.io.event_reader import EventReader
    from gevsim.tonemap import ToneMap

    with EventReader(path) as r:
        if r.count("events") < MIN_EVENTS:
            raise ConfigError(f"{r.count('events')} DVS events: EVREAL cannot load a sequence with fewer than "
                              f"{MIN_EVENTS}", source=str(path))
        events, (frames, t_us), w, h = r.read("events"), r.frames("log_photocurrent"), r.width, r.height
    tone = ToneMap.from_ground_truth(frames)
    images = np.rint(tone(frames) * 255.0).astype(np.uint8)
    export_evreal(folder, events, images, t_us, width=w, height=h,
                  extra_metadata={"tone_map_ln": [tone.low, tone.high], **(extra_metadata or {})})
    return {"events": len(events)}
