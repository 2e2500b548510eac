"""float32 OpenEXR images with the OpenEXR package (Mitsuba's async bitmap writer hung here)."""

from __future__ import annotations

import json
import os

import numpy as np
import OpenEXR

from gevsim.io._h5discard import disk_error
from gevsim.io.atomic import atomic_path

_CHANNELS = {1: ("Y",), 3: ("R", "G", "B")}


def _channels(image, *, prefix: str, what: str) -> dict:
    """``{prefix + 'R': plane, ...}`` of an (H, W), (H, W, 1) or (H, W, 3) image, as float32."""
    image = np.asarray(image, dtype=np.float32)
    if image.ndim == 2:
        image = image[..., None]
    if image.ndim != 3 or image.shape[2] not in _CHANNELS:
        raise ValueError(f"{what}: expected (H, W), (H, W, 1) or (H, W, 3), got shape {image.shape}")
    return {prefix + n: np.ascontiguousarray(image[..., i]) for i, n in enumerate(_CHANNELS[image.shape[2]])}


def _write(path, channels: dict, metadata: dict | None) -> None:
    """Write float32 channels as one ZIP-compressed EXR, atomically, with ``metadata`` as JSON."""
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    if metadata:
        header["gevsim"] = json.dumps(metadata, sort_keys=True)
    with atomic_path(path, suffix=".exr") as tmp:
        with OpenEXR.File(header, channels) as f:
            try:
                f.write(str(tmp))
            except RuntimeError as exc:  # OpenEXR reports a failed write (a full disk) as RuntimeError
                error = disk_error(exc, path)  # "... No space left on device." as OSError(ENOSPC, ..., path)
                if error is None:
                    raise
                raise error from exc


def write_exr(path: str | os.PathLike, image: np.ndarray, *, metadata: dict | None = None) -> None:
    """Write an (H, W), (H, W, 1) or (H, W, 3) image as float32 EXR (ZIP), atomically.

    ``metadata`` is stored as a JSON string attribute ``gevsim``.
    """
    _write(path, _channels(image, prefix="", what="write_exr"), metadata)


def read_exr(path: str | os.PathLike) -> tuple[np.ndarray, dict]:
    """Read an EXR written by :func:`write_exr`: float32 (H, W, C) and its metadata."""
    with OpenEXR.File(str(path), separate_channels=True) as f:
        header = f.header()
        chans = f.channels()
        names = [n for n in ("R", "G", "B") if n in chans] or [n for n in ("Y",) if n in chans] or sorted(chans)
        image = np.stack([np.array(chans[n].pixels, dtype=np.float32) for n in names], axis=-1)
        meta = header.get("gevsim")
    return image, (json.loads(meta) if isinstance(meta, str) else {})


def write_exr_layers(path: str | os.PathLike, layers: dict, *, metadata: dict | None = None) -> None:
    """Write named (H, W, C) float32 images (C = 1 or 3) into one EXR, atomically.

    Channels are named ``<layer>.R``/``.G``/``.B`` (or ``<layer>.Y``).
    """
    channels = {}
    for name, image in layers.items():
        channels.update(_channels(image, prefix=f"{name}.", what=f"write_exr_layers: layer {name!r}"))
    _write(path, channels, metadata)


def read_exr_layers(path: str | os.PathLike) -> tuple[dict, dict]:
    """Read an EXR written by :func:`write_exr_layers`: ``{layer: (H, W, C) float32}`` and its metadata."""
    with OpenEXR.File(str(path), separate_channels=True) as f:
        header = f.header()
        chans = {n: np.array(c.pixels, dtype=np.float32) for n, c in f.channels().items()}
        meta = header.get("gevsim")
    layers = {}
    for full in chans:
        layer = full.rsplit(".", 1)[0]
        if layer in layers:
            continue
        names = [f"{layer}.{c}" for c in ("R", "G", "B") if f"{layer}.{c}" in chans] or [f"{layer}.Y"]
        layers[layer] = np.stack([chans[n] for n in names], axis=-1)
    return layers, (json.loads(meta) if isinstance(meta, str) else {})
