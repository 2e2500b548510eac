"""PNG figures for people: irradiance contact sheets and lamp waveforms.

Needs the ``plot`` extra (matplotlib); uses the non-interactive Agg backend.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from gevsim.errors import MissingExtraError
from gevsim.io import atomic_path
from gevsim.tonemap import ToneMap

if TYPE_CHECKING:
    from matplotlib.colorbar import Colorbar
    from matplotlib.figure import Figure

    from gevsim.illumination import Waveform
    from gevsim.render.basis import BasisSet


def _pyplot():
    try:
        import matplotlib
    except ImportError as exc:  # pragma: no cover - depends on the install
        raise MissingExtraError("plots need matplotlib: pip install 'gevsim[plot]'") from exc
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def save_figure(fig: Figure, path: str | os.PathLike) -> None:
    """Write a figure as a PNG atomically (temporary name, then rename) and close it."""
    import matplotlib.pyplot as plt

    with atomic_path(path, suffix=".png") as tmp:
        fig.savefig(tmp, dpi=100, format="png")
    plt.close(fig)


#: A contact sheet's grey scale spans at most this many decades of irradiance below its bright end.
SHEET_DECADES = 4.5
#: Percentiles of the lit pixels' luminance giving the sheet's bright end and (within SHEET_DECADES) its dark end.
SHEET_PERCENTILES = (0.5, 99.5)
#: A pixel is lit when its luminance is within this many decades of the sequence's brightest 0.1 %.
LIT_DECADES = 8.0
#: Colour of the pixels darker than the sheet's scale (the colour bar's ``extend="min"`` triangle).
UNDER_RGB = (0.12, 0.16, 0.45)


def sheet_scale(frames: np.ndarray) -> ToneMap:
    """The log scale of a contact sheet, set by the lit scene and not by an empty background.

    The lit pixels are those (of every frame) whose luminance is positive and within
    :data:`LIT_DECADES` of the brightest 0.1 %: a black background (zero, or the renderer's
    tiny residue ten decades down) is not lit. The bright end is the lit pixels' 99.5th percentile of
    luminance; the dark end their 0.5th percentile, but never more than :data:`SHEET_DECADES` (4.5)
    decades below the bright end, about what a person tells apart on a grey scale. Pixels darker
    than the dark end are clipped, and drawn as such (:data:`UNDER_RGB`). A sequence with no
    positive pixel gets :meth:`ToneMap.from_ground_truth` of its clamped logarithm.
    """
    from gevsim.optics import luminance

    y = np.asarray(luminance(np.asarray(frames, np.float64)), np.float64).ravel()
    positive = y[np.isfinite(y) & (y > 0)]
    if positive.size == 0:
        return ToneMap.from_ground_truth(np.log(np.maximum(np.asarray(frames, np.float64), 1e-12)))
    lit = positive[positive >= np.percentile(positive, 99.9) * 10.0 ** -LIT_DECADES]
    low, high = np.log(np.percentile(lit, SHEET_PERCENTILES))
    low = max(float(low), float(high) - SHEET_DECADES * np.log(10.0))
    if high <= low:  # a flat image: centre it
        low, high = low - 0.5, high + 0.5
    return ToneMap(float(low), float(high))


def contact_sheet(frames: np.ndarray, times_s: Sequence[float], path: str | os.PathLike, *, title: str = "",
                  max_frames: int = 12) -> None:
    """Grid of up to ``max_frames`` log tone-mapped frames labelled with time and mean illuminance, on one
    scale for the whole sequence set by the lit scene (:func:`sheet_scale`); darker pixels drawn in
    :data:`UNDER_RGB`."""
    plt = _pyplot()
    from gevsim.optics import illuminance_lux, luminance

    idx = np.unique(np.linspace(0, len(frames) - 1, min(max_frames, len(frames))).round().astype(int))
    tone = sheet_scale(frames)
    cols = min(4, len(idx))
    rows = int(np.ceil(len(idx) / cols))
    h, w = frames.shape[1:3]
    fig, axes = plt.subplots(rows, cols, figsize=(3.2 * cols, 3.2 * rows * h / w + 0.6), squeeze=False)
    for ax in axes.ravel():
        ax.axis("off")
    for ax, i in zip(axes.ravel(), idx):
        frame = np.asarray(frames[i], np.float64)
        frame = frame if frame.ndim == 3 else frame[..., None]
        y = luminance(frame if frame.shape[-1] == 3 else frame[..., 0])
        img = tone(np.log(np.maximum(frame, 1e-300)))
        img = np.repeat(img, 3, axis=-1) if img.shape[-1] == 1 else img
        img[y < np.exp(tone.low)] = UNDER_RGB  # clipped: darker than the scale
        ax.imshow(img, vmin=0, vmax=1, interpolation="nearest")
        ax.set_title(f"t = {1e3 * times_s[i]:.2f} ms, {float(illuminance_lux(y).mean()):.1f} lx", fontsize=9)
    fig.suptitle(f"{title}: focal-plane irradiance (log scale set by the lit scene)", fontsize=11)
    fig.tight_layout(rect=(0.0, 0.0, 0.86, 1.0))
    _lux_scale(fig, tone)
    save_figure(fig, path)


def _lux_scale(fig: Figure, tone: ToneMap) -> Colorbar:
    """A scale bar beside a contact sheet: grey level -> focal-plane illuminance (lx; 683 x the photopic-
    equivalent irradiance the log tone map spans); its triangle at the bottom: darker than the scale."""
    import matplotlib as mpl

    from gevsim.optics.photometry import K_M_LM_PER_W

    cax = fig.add_axes((0.89, 0.12, 0.025, 0.72))
    cmap = mpl.colormaps["gray"].with_extremes(under=UNDER_RGB)
    bar = fig.colorbar(mpl.cm.ScalarMappable(norm=mpl.colors.Normalize(0.0, 1.0), cmap=cmap), cax=cax,
                       extend="min")
    ticks = np.linspace(0.0, 1.0, 5)
    bar.set_ticks(ticks.tolist())
    bar.set_ticklabels([f"{K_M_LM_PER_W * np.exp(tone.low + v * (tone.high - tone.low)):.3g}" for v in ticks])
    bar.set_label("illuminance on the chip (lx, log scale; triangle: darker, clipped)")
    return bar


def waveform_samples(wf: Waveform, t_end_s: float, n: int = 4000) -> tuple[np.ndarray, np.ndarray]:
    """(t, w(t)) to draw a waveform over [0, t_end]: ``n`` even samples plus a pair just either side of
    each breakpoint (a PWM's edges), so a line through them draws a jump as a vertical step, not as
    the slope between two grid samples."""
    t = np.linspace(0.0, t_end_s, n)
    bp = np.asarray(wf.breakpoints_s(0.0, t_end_s), float)
    eps = 1e-9 * t_end_s
    t = np.unique(np.clip(np.concatenate([t, bp - eps, bp + eps]), 0.0, t_end_s))
    return t, np.asarray(wf(t), float)


def waveform_plot(basis: BasisSet, times_s: Sequence[float], mean_lux: Sequence[float], path: str | os.PathLike, *,
                  title: str = "") -> None:
    """Lamp waveforms (top) and mean focal-plane illuminance of the frames (bottom)."""
    plt = _pyplot()
    t_end = max(float(times_s[-1]) if len(times_s) else 0.0, 1e-6)
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(9, 5.5), sharex=True)
    for name, wf in zip(basis.groups, basis.waveforms):
        t, w = waveform_samples(wf, t_end)
        top.plot(1e3 * t, w, label=f"{name}: {type(wf).__name__}")
    top.set_ylabel("relative output w(t)")
    top.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8)  # beside the curves, not over them
    top.grid(alpha=0.3)
    bottom.plot(1e3 * np.asarray(times_s), mean_lux, "o-", ms=3)
    bottom.set_xlabel("time (ms)")
    bottom.set_ylabel("mean focal-plane illuminance (lx)")
    bottom.grid(alpha=0.3)
    fig.suptitle(f"{title}: lamp waveforms and mean irradiance")
    fig.tight_layout()
    save_figure(fig, path)
