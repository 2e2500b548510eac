"""The training set of ``gevsim train``: a `gevsim dataset` folder's shards (or a list of emulation files, as
:func:`gevsim.evaluation.compare.emulation_files` lists them),
each encoded once (:func:`gevsim.learn.encode.encode`) and held in memory with its zero-mean ground-truth ln
frames; random mini-batches of whole sequences, cropped and flipped."""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from gevsim.errors import ConfigError
from gevsim.io import EventReader
from gevsim.render.input_files import sha256_of

__all__ = ["Sequence_", "batch", "data_digest", "load_sequences"]


@dataclass(frozen=True)
class Sequence_:
    """One encoded sequence: inputs (M, C, H, W) float32 and targets (M, H, W) float32 of zero mean."""

    inputs: np.ndarray
    targets: np.ndarray
    source: str
    encoding: str


def _config_digest(folder: Path) -> dict:
    """The dataset config's SHA-256 (its text as ``dataset.json`` records it) and its sequence count: what
    regenerates the same shards (dataset.json itself also records each sequence's wall time)."""
    try:
        index = json.loads((folder / "dataset.json").read_text())
        text = index["config_toml"]
        return {"config_sha256": hashlib.sha256(text.encode()).hexdigest(), "config_source": index.get("source"),
                "sequences": len(index.get("sequences", []))}
    except (OSError, ValueError, KeyError, TypeError):
        return {}


def data_digest(data: Sequence[str | os.PathLike], files: Sequence[Path]) -> dict:
    """Provenance of the training data: each dataset folder's dataset.json SHA-256, or each file's."""
    out: dict = {}
    for item in data:
        path = Path(item)
        if path.is_dir() and (path / "dataset.json").is_file():
            out[str(path)] = {"dataset.json sha256": sha256_of(path / "dataset.json"), **_config_digest(path)}
        elif path.is_dir():
            out[str(path)] = {"shards sha256": {f.name: sha256_of(f) for f in files if f.parent.parent == path}}
        else:
            out[str(path)] = {"sha256": sha256_of(path)}
    return out


def load_sequences(files: Sequence[Path], encoding: str, *, reference: str = "flicker",
                   progress: Callable[[int, int], None] | None = None) -> list[Sequence_]:
    """Encode every file once for ``encoding`` (a key of :data:`gevsim.learn.encode.ENCODINGS`), with its
    ground truth (``reference``: flicker or no-flicker) as zero-mean ln frames."""
    from gevsim.evaluation.runner import ground_truth
    from gevsim.learn.encode import encode

    out = []
    for i, path in enumerate(files):
        with EventReader(path) as r:
            gt, t_us, is_log = ground_truth(r, reference)
            if not is_log:
                raise ConfigError("holds frame-mode intensities, not ln ground truth: train on scene-mode "
                                  "files (`gevsim dataset`)", source=str(path))
            inputs = encode(r, encoding, t_us, gt.shape[1:])
        targets = (gt - gt.mean(axis=(1, 2), keepdims=True)).astype(np.float32)
        out.append(Sequence_(inputs, targets, str(path), encoding))
        if progress:
            progress(i + 1, len(files))
    return out


def batch(sequences: Sequence[Sequence_], rng: np.random.Generator, *, size: int,
          crop: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """A mini-batch of ``size`` random sequences (with replacement), each cut to the shortest one's length,
    randomly cropped to ``crop`` (H, W) (at most each sequence's size; even sizes at even offsets, which keep
    the resolution-compressed pairs and the threshold pattern's parity) and flipped left-right and up-down at
    random: inputs (B, T, C, h, w) and targets (B, T, h, w), targets zero mean per frame again."""
    picks = rng.integers(0, len(sequences), size=size)
    chosen = [sequences[int(i)] for i in picks]
    t = min(len(s.targets) for s in chosen)
    h = min([crop[0]] + [s.targets.shape[1] for s in chosen]) // 2 * 2
    w = min([crop[1]] + [s.targets.shape[2] for s in chosen]) // 2 * 2
    xs, ys = [], []
    for s in chosen:
        y0 = 2 * int(rng.integers(0, (s.targets.shape[1] - h) // 2 + 1))
        x0 = 2 * int(rng.integers(0, (s.targets.shape[2] - w) // 2 + 1))
        x = s.inputs[:t, :, y0:y0 + h, x0:x0 + w]
        y = s.targets[:t, y0:y0 + h, x0:x0 + w]
        if rng.random() < 0.5:  # a flip is the same scene seen in a mirror
            x, y = _flip(x, -1, s.encoding), y[..., ::-1]
        if rng.random() < 0.5:
            x, y = _flip(x, -2, s.encoding), y[..., ::-1, :]
        xs.append(x)
        ys.append(y - y.mean(axis=(1, 2), keepdims=True))
    return np.ascontiguousarray(np.stack(xs)), np.ascontiguousarray(np.stack(ys))


def _flip(x: np.ndarray, axis: int, encoding: str) -> np.ndarray:
    """Flip inputs (T, C, h, w) along ``axis`` (-1: x, -2: y). A DVS encoding's channels only move. A gradient
    encoding's channel along that axis changes sign, and the forward difference I(x+1) - I(x), stored at x,
    belongs at x - 1 once flipped (the last column gets 0, no comparator there); a resolution-compressed
    pair's value fills both of its pixels, which a flip of an even size keeps together: it only moves."""
    out = np.flip(x, axis=axis).copy()
    if encoding in ("gradient", "gradient_rc"):
        a = 0 if axis == -1 else 1
        out[:, a] *= -1
        if encoding == "gradient":
            g = np.moveaxis(out[:, a], axis, 0)  # a view: the axis first
            g[:-1] = g[1:].copy()
            g[-1] = 0
    return out
