"""float32 OpenEXR images with the OpenEXR package (Mitsuba's async bitmap writer hung here)."""

from __future__ import annotations

import json
import os

import numpy as np
import OpenEXR

from gevsim.io.atomic import atomic_path

_CHANNELS = {1: ("Y",), 3: ("R", "G", "B")}


def write_exr(path: str | os.PathLike, image: np.ndarray, *, metadata: dict | None = None) -> None:
    """Write an (H, W), (H, W, 1) or (H, W, 3) image as float32 EXR (ZIP), atomically.

    ``metadata`` is stored as a JSON string attribute ``gevsim``.
    """
    image = np.asarray(image, dtype=np.float32)
    if image.ndim == 2:
        image = image[..., None]
    if image.ndim != 3 or image.shape[2] not in _CHANNELS:
        raise ValueError(f"write_exr: expected (H, W), (H, W, 1) or (H, W, 3), got shape {image.shape}")
    names = _CHANNELS[image.shape[2]]
    channels = {n: np.ascontiguousarray(image[..., i]) for i, n in enumerate(names)}
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    if metadata:
        header["gevsim"] = json.dumps(metadata, sort_keys=True)
    with atomic_path(path, suffix=".exr") as tmp:
        with OpenEXR.File(header, channels) as f:
            f.write(str(tmp))


def read_exr(path: str | os.PathLike) -> tuple[np.ndarray, dict]:
    """Read an EXR written by :func:`write_exr`: float32 (H, W, C) and its metadata."""
    with OpenEXR.File(str(path), separate_channels=True) as f:
        header = f.header()
        chans = f.channels()
        names = [n for n in ("R", "G", "B") if n in chans] or [n for n in ("Y",) if n in chans] or sorted(chans)
        image = np.stack([np.array(chans[n].pixels, dtype=np.float32) for n in names], axis=-1)
        meta = header.get("gevsim")
    return image, (json.loads(meta) if isinstance(meta, str) else {})
