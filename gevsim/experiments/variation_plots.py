"""Plots of the runs around the headline: the tornado of the ratio over the assumed numbers, and the trade-off
of flicker- against noise-induced events and of reconstruction against bandwidth."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from gevsim.emulation.emulators import EMULATORS, HEADLINE
from gevsim.experiments.answer import pixel_ratio
from gevsim.experiments.variation_report import Point

BASELINE, CANDIDATE = HEADLINE
TORNADO_FILE = "tornado.png"
TRADEOFF_FILE = "tradeoff.png"


def _finite(iv: Any) -> bool:
    """A ratio with a positive finite estimate (its interval may be one-sided: then its whisker is cut)."""
    return iv is not None and math.isfinite(iv.estimate) and iv.estimate > 0


def _whisker(iv: Any) -> list[list[float]]:
    """The error bar of a ratio on a log axis; an unbounded side is drawn to 0 length."""
    low = iv.estimate - iv.low if math.isfinite(iv.low) and iv.low > 0 else 0.0
    high = iv.high - iv.estimate if math.isfinite(iv.high) else 0.0
    return [[max(low, 0.0)], [max(high, 0.0)]]


def tornado(folder: Path, head: dict, variation_rows: list[dict], plt: Any) -> tuple[str, str] | None:
    """One bar per assumed number from the ratio at one end of its range to the other (95 % intervals as
    whiskers), the widest on top; the joint draws as a row of points; the headline's ratio as a line."""
    ref = pixel_ratio(head)[0]
    sens = [r for r in variation_rows if r.get("variation") == "sensitivity"]
    if not sens or ref is None or not _finite(ref):
        return None
    keys = list(dict.fromkeys(r["variation_key"] for r in sens))
    ends = {k: [(r["variation_end"], pixel_ratio(r)[0]) for r in sens if r["variation_key"] == k] for k in keys}
    kept = {k: [(end, iv) for end, iv in v if iv is not None and _finite(iv)] for k, v in ends.items()}

    def span(k: str) -> float:
        return max((max(iv.estimate / ref.estimate, ref.estimate / iv.estimate) for _, iv in kept[k]), default=1.0)

    keys.sort(key=span)
    joint = [iv for r in variation_rows if r.get("variation") == "joint"
             and (iv := pixel_ratio(r)[0]) is not None and _finite(iv)]
    fig, ax = plt.subplots(figsize=(8, 1.2 + 0.45 * (len(keys) + bool(joint))), constrained_layout=True)
    for y, k in enumerate(keys):
        values = [iv.estimate for _, iv in kept[k]] + [ref.estimate]
        ax.barh(y, max(values) - min(values), left=min(values), color="#9ecae1", edgecolor="#3182bd", height=0.6)
        for end, iv in kept[k]:
            ax.errorbar(iv.estimate, y, xerr=_whisker(iv), fmt="o",
                        color="#08519c", ms=4, capsize=2)
            ax.annotate(end, (iv.estimate, y), textcoords="offset points", xytext=(0, 7), ha="center", fontsize=7)
    if joint:
        y = len(keys)
        ax.plot([iv.estimate for iv in joint], [y] * len(joint), "D", color="#636363", ms=5)
        keys = keys + ["all at once (joint draws)"]
    ax.axvline(ref.estimate, color="k", lw=1)
    if math.isfinite(ref.low) and ref.low > 0 and math.isfinite(ref.high):
        ax.axvspan(ref.low, ref.high, color="k", alpha=0.08, lw=0)
    ax.set_yticks(range(len(keys)), keys, fontsize=8)
    ax.set_xscale("log")
    ax.set_xlabel(f"{EMULATORS[BASELINE].label}/{EMULATORS[CANDIDATE].label} flicker-induced events at the pixels "
                  "(ratio)")
    ax.set_title(f"How far the ratio moves with each assumed number (headline {pixel_ratio(head)[1]}: line, band)",
                 fontsize=9)
    fig.savefig(folder / TORNADO_FILE, dpi=110)
    plt.close(fig)
    return TORNADO_FILE, ("The DVS/gradient ratio of flicker-induced events at the pixels with each assumed number of "
                          "the sensor preset at the ends of its plausible range (bars; whiskers: 95 % Fieller "
                          "intervals, cut where one-sided), and with all of them drawn at once (diamonds); the line "
                          "and band are the headline run's ratio and interval.")


#: Rates below this (ev/px/s) are drawn at it on the trade-off's log axes (with the interval's clipped part).
LOG_FLOOR = 1e-2


def _log_point(iv: Any) -> tuple[float, list[list[float]]]:
    """A rate and its error bar for a log axis: at least :data:`LOG_FLOOR`, the bar clipped there."""
    v = max(iv.estimate, LOG_FLOOR)
    return v, [[max(v - max(iv.low, LOG_FLOOR), 0.0)], [max(iv.high - v, 0.0)]]


def tradeoff(folder: Path, pts: list[Point], cap: float | None, plt: Any) -> tuple[str, str] | None:
    """Left: flicker- against noise-induced events at the pixels, one point per (stream, setting), numbered.
    Right: the best reconstruction's SSIM against the events the pixels make, with the bus cap."""
    settings = list(dict.fromkeys(p.setting for p in pts))
    if len(settings) < 2:
        return None
    fig, (left, right) = plt.subplots(1, 2, figsize=(12, 5.5), constrained_layout=True)
    for p in pts:
        color = EMULATORS[p.emulator].color
        marker = "o" if p.emulator == BASELINE else "s"
        tag = str(settings.index(p.setting))
        (x, xerr), (y, yerr) = _log_point(p.noise), _log_point(p.flicker)
        left.errorbar(x, y, xerr=xerr, yerr=yerr, fmt=marker, color=color, ms=6, capsize=2)
        left.annotate(tag, (x, y), textcoords="offset points", xytext=(6, 4), fontsize=9, color=color)
        if math.isfinite(p.ssim):
            right.plot(p.made, p.ssim, marker, color=color, ms=8, mfc="none" if p.at_cap else color)
            right.annotate(tag, (p.made, p.ssim), textcoords="offset points", xytext=(6, 4), fontsize=9, color=color)
    for e in HEADLINE:
        left.plot([], [], "o" if e == BASELINE else "s", color=EMULATORS[e].color, label=EMULATORS[e].label)
    left.set(xscale="log", yscale="log", xlabel=f"noise-induced ev/px/s at the pixels (floor {LOG_FLOOR:g})",
             ylabel=f"flicker-induced ev/px/s at the pixels (floor {LOG_FLOOR:g})")
    left.set_title("Flicker against noise, at the pixels (lower left wins)", fontsize=10)
    left.legend(fontsize=8, loc="upper left")
    if cap:
        right.axvline(cap, color="k", ls="--", lw=1)
        right.annotate(f"bus cap {cap:.3g} ev/px/s", (cap, 0.02), xycoords=("data", "axes fraction"), rotation=90,
                       fontsize=8, ha="right")
    right.set(xscale="log", xlabel="events the pixels make, ev/px/s (hollow: more than the bus delivers)",
              ylabel="best reconstruction SSIM (of what the bus delivered)")
    right.set_title("Reconstruction against bandwidth", fontsize=10)
    right.xaxis.set_minor_formatter(plt.matplotlib.ticker.NullFormatter())  # minor labels collide on a short decade
    fig.text(0.01, -0.01, "\n".join(f"{i}: {s}" for i, s in enumerate(settings)), fontsize=8, va="top")
    fig.savefig(folder / TRADEOFF_FILE, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return TRADEOFF_FILE, ("Design settings around the headline run (numbered; 0 is the headline). Left: flicker- "
                           "against noise-induced events at the pixels, before the bus (95 % intervals). Right: the "
                           "best reconstruction's SSIM against the events the pixels make; hollow markers are "
                           "streams the bus cannot carry whole (at its cap, dashed).")
