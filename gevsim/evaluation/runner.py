"""Reconstruct frames from an emulation file and score them against its ground truth.

Gradient methods (``sor``, ``dct``) decode the gradient-event stream from the
stored initial ternary state up to each ground-truth frame and solve the
Poisson problem (Lehtonen et al.); brightness methods (``direct``,
``high_pass``, ``complementary``) integrate brightness events (Scheerlinck,
Barnes & Mahony 2018). Events carry no absolute level: every reconstruction
gets the ground-truth mean of its frame (the papers' protocol) or, with
``mean="photodiode"``, the log of the mean irradiance that one extra global
photodiode would measure. Scores are EVREAL's, on frames tone-mapped by
:class:`~gevsim.reconstruct.tonemap.ToneMap`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from gevsim.emulation import layout
from gevsim.errors import ConfigError, suggest
from gevsim.events import decode
from gevsim.io import EventReader
from gevsim.metrics import frame_metrics
from gevsim.reconstruct import brightness
from gevsim.reconstruct.gradient import GradientReconstructor, global_photodiode_mean
from gevsim.reconstruct.tonemap import ToneMap

GRADIENT_METHODS = ("dct", "sor")
BRIGHTNESS_METHODS = ("direct", "high_pass", "complementary")
METHODS = GRADIENT_METHODS + BRIGHTNESS_METHODS
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
                          f"choose from {', '.join(REFERENCES)}", key="--reference")
    for name, is_log in ((REFERENCES[reference], True), (layout.INTENSITY, False)):
        if name in reader.frame_names:
            images, t_us = reader.frames(name)
            return images.astype(np.float64), np.asarray(t_us, np.int64), is_log
    raise ConfigError("holds no ground-truth frames (log_photocurrent or intensity)", source=str(reader.path))


def _level(gt: np.ndarray, is_log: bool, mean: str) -> float:
    if mean == "ground-truth":
        return float(gt.mean())
    return global_photodiode_mean(gt) if is_log else float(gt.mean())


def reconstruct_file(path: str | Path, method: str, *, mean: str = "ground-truth", rc: bool = False,
                     c: float = 3.6, contrast: float | None = None,
                     reference: str = "flicker") -> tuple[Reconstruction, np.ndarray, ToneMap]:
    """Reconstruct at every ground-truth frame time; returns (reconstruction, ground truth, tone map).

    ``reference="no-flicker"`` scores against the scene with every lamp at its mean, the
    reference of the flicker-robustness question (what is in the scene, not the lamp phase).
    ``contrast`` (the ln step of a brightness event) defaults to the DVS thresholds stored in
    the file (the sensor's nominal ON/OFF thresholds), else 0.2.
    """
    if method not in METHODS:
        raise ConfigError(f"unknown method {method!r}{suggest(method, METHODS)}; choose from {', '.join(METHODS)}",
                          key="--method")
    if mean not in MEANS:
        raise ConfigError(f"unknown mean {mean!r}; choose from {', '.join(MEANS)}", key="--mean")
    with EventReader(path) as r:
        gt, t_us, is_log = ground_truth(r, reference)
        if method in GRADIENT_METHODS:
            rec = _gradient(r, gt, t_us, method, rc=rc, c=c)
        else:
            rec = _brightness(r, gt, t_us, method, contrast=contrast, is_log=is_log)
    for k in range(len(gt)):
        rec.frames[k] += _level(gt[k], is_log, mean) - rec.frames[k].mean()
    tone = ToneMap.from_ground_truth(gt) if is_log else ToneMap()
    rec.metrics = [frame_metrics(tone(rec.frames[k]), tone(gt[k])) for k in range(len(gt))]
    return rec, gt, tone


def _gradient(r: EventReader, gt, t_us, method, *, rc, c) -> Reconstruction:
    name = "gradient_rc" if rc else "gradient"
    stream = f"{name}_events"
    if stream not in r.streams:
        raise ConfigError(f"holds no {stream} stream (emulate with '{name}' among the emulators)", source=str(r.path))
    theta = r.array(layout.thresholds_key(name)).astype(np.float64)
    state = r.array(layout.initial_state_key(name)).astype(np.int8)
    solver = GradientReconstructor(gt.shape[1:], theta, rc=rc, method=method, c=c)
    frames = np.empty_like(gt)
    previous = None
    for k, t in enumerate(t_us):
        start = None if previous is None else previous + 1
        events = r.read(stream, start, int(t) + 1)  # events in (previous frame, this frame]
        state = decode(events, state)
        frames[k] = solver.frame(state)
        previous = int(t)
    return Reconstruction(method, stream, t_us, frames)


def _brightness(r: EventReader, gt, t_us, method, *, contrast, is_log) -> Reconstruction:
    if contrast is None:
        try:
            on, off = (float(v) for v in r.array(layout.thresholds_key("dvs")))
        except (KeyError, ConfigError):
            on = off = 0.2
    else:
        on = off = float(contrast)
    if "events" not in r.streams:
        raise ConfigError("holds no brightness event stream (emulate with 'dvs')", source=str(r.path))
    events = r.read("events", None, int(t_us[-1]) + 1)
    h, w = gt.shape[1:]
    if method == "direct":  # events only: starts from a flat image, like the filters
        frames = brightness.direct_integration(events, t_us, width=w, height=h, contrast_on=on, contrast_off=off)
    elif method == "high_pass":
        frames = brightness.high_pass_filter(events, t_us, width=w, height=h, contrast=(on, off))
    else:
        if layout.APS not in r.frame_names:
            raise ConfigError("the complementary filter needs APS frames: emulate with aps = true",
                              source=str(r.path), key="--method")
        aps, aps_t = r.frames(layout.APS)
        offset = float(r.array_attrs(f"/frames/{layout.APS}").get("offset_dn", 0.0))
        aps_log = np.log(np.maximum(aps.astype(np.float64) - offset, 1.0))  # DN above black level, in ln
        frames = brightness.complementary_filter(events, aps_log, aps_t, t_us, width=w, height=h,
                                                 contrast=(on, off))
    if not is_log:  # frame mode compares intensities
        frames = np.exp(frames) - 1.0 / 255
    return Reconstruction(method, "events", t_us, np.asarray(frames, np.float64))
