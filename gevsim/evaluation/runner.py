"""Reconstruct frames from an emulation file and score them against its ground truth.

The methods are those of :data:`gevsim.evaluation.methods.METHODS`. Events carry
no absolute level: every reconstruction gets the ground-truth mean of its frame
(the papers' protocol) or, with
``mean="photodiode"``, the log of the mean irradiance that one extra global
photodiode would measure. Scores are EVREAL's, on frames tone-mapped by
:class:`~gevsim.tonemap.ToneMap`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from gevsim.emulation import layout
from gevsim.errors import ConfigError, suggest
from gevsim.evaluation.methods import check_method
from gevsim.io import EventReader
from gevsim.metrics import frame_metrics
from gevsim.reconstruct.gradient import global_photodiode_mean
from gevsim.tonemap import ToneMap

MEANS = ("ground-truth", "photodiode")


@dataclass
class Reconstruction:
    method: str
    stream: str
    t_us: np.ndarray
    frames: np.ndarray  # (M, H, W), same units as the ground truth
    metrics: list = field(default_factory=list)  # per frame dicts

    def mean_metrics(self) -> dict:
        keys = ("mse", "ssim", "psnr")
        return {k: float(np.mean([m[k] for m in self.metrics if np.isfinite(m[k])])) for k in keys}


REFERENCES = {"flicker": layout.LOG_PHOTOCURRENT, "no-flicker": layout.LOG_PHOTOCURRENT_NO_FLICKER}


def ground_truth(reader: EventReader, reference: str = "flicker") -> tuple[np.ndarray, np.ndarray, bool]:
    """(frames, t_us, is_log): the log photocurrent of an emulation (as lit at each instant, or
    with every lamp at its mean for ``reference="no-flicker"``), or frame mode's intensities."""
    if reference not in REFERENCES:
        raise ConfigError(f"unknown reference {reference!r}{suggest(reference, REFERENCES)}; "
                          f"choose from {', '.join(REFERENCES)}", key="reference")
    for name, is_log in ((REFERENCES[reference], True), (layout.INTENSITY, False)):
        if name in reader.frame_names:
            images, t_us = reader.frames(name)  # checked: shape, finite, times sorted within the recording
            if images.ndim != 3 or not len(images) or images.dtype.kind != "f":
                raise ConfigError(f"ground-truth frames {name!r} must be (N >= 1, H, W) floats, got "
                                  f"{images.shape} of {images.dtype}", source=str(reader.path))
            return images.astype(np.float64), np.asarray(t_us, np.int64), is_log
    raise ConfigError("holds no ground-truth frames (log_photocurrent or intensity)", source=str(reader.path))


def _level(gt: np.ndarray, is_log: bool, mean: str) -> float:
    if mean == "ground-truth":
        return float(gt.mean())
    return global_photodiode_mean(gt) if is_log else float(gt.mean())


def reconstruct_file(path: str | Path, method: str, *, mean: str = "ground-truth", c: float = 3.6,
                     contrast_ln: float | None = None,
                     reference: str = "flicker") -> tuple[Reconstruction, np.ndarray, ToneMap]:
    """Reconstruct at every ground-truth frame time; returns (reconstruction, ground truth, tone map).

    ``method`` is a full name of :data:`~gevsim.evaluation.methods.METHODS` (``"dct"``,
    ``"dct_rc"``, ``"direct"``, ...). ``reference="no-flicker"`` scores against the scene with
    every lamp at its mean, the reference of the flicker-robustness question (what is in the
    scene, not the lamp phase). ``contrast_ln`` (the ln step of a brightness event) defaults to the
    DVS thresholds stored in the file (the sensor's nominal ON/OFF thresholds), else 0.2.
    """
    try:
        entry = check_method(method)
    except ValueError as exc:
        raise ConfigError(str(exc), key="method") from None
    if mean not in MEANS:
        raise ConfigError(f"unknown mean {mean!r}; choose from {', '.join(MEANS)}", key="mean")
    if isinstance(c, bool) or not isinstance(c, (int, float)) or not math.isfinite(c) or c <= 0:
        raise ConfigError(f"the Poisson scale must be a finite number > 0, got {c!r}", key="c")
    if contrast_ln is not None and (isinstance(contrast_ln, bool) or not isinstance(contrast_ln, (int, float))
                                    or not math.isfinite(contrast_ln) or contrast_ln <= 0):
        raise ConfigError(f"the contrast step must be a finite number > 0 (ln units), got {contrast_ln!r}",
                          key="contrast_ln")
    with EventReader(path) as r:
        gt, t_us, is_log = ground_truth(r, reference)
        frames = entry.run(r, gt, t_us, c=c, contrast_ln=contrast_ln, is_log=is_log)
    rec = Reconstruction(method, entry.stream, t_us, frames)
    for k in range(len(gt)):
        rec.frames[k] += _level(gt[k], is_log, mean) - rec.frames[k].mean()
    tone = ToneMap.from_ground_truth(gt) if is_log else ToneMap()
    rec.metrics = [frame_metrics(tone(rec.frames[k]), tone(gt[k])) for k in range(len(gt))]
    return rec, gt, tone
