"""The report's sections about the runs around the headline (:mod:`gevsim.experiments.variations`): how far
the answer moves with what was assumed (a table beside the tornado plot) and where gradient events win (the
trade-off of flicker-induced, noise-induced events, reconstruction and bandwidth)."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from gevsim.emulation.emulators import EMULATORS, HEADLINE
from gevsim.evaluation.methods import METHODS
from gevsim.experiments.aggregate import interval_of
from gevsim.experiments.answer import pixel_ratio
from gevsim.metrics.attribution import Interval

BASELINE, CANDIDATE = HEADLINE
HEADLINE_SETTING = "headline"


@dataclasses.dataclass(frozen=True)
class Point:
    """One stream at one setting: flicker- and noise-induced rates at the pixels (intervals), what the pixels
    made and the bus delivered (ev/px/s), and its best reconstruction (SSIM, method)."""

    emulator: str
    setting: str
    flicker: Interval
    noise: Interval
    made: float
    delivered: float
    ssim: float
    method: str
    at_cap: bool


def _rate(iv: Interval) -> str:
    """An interval, or "0 (in every repeat)" where every repeat counted none."""
    return "0 (in every repeat)" if iv.low == iv.high == iv.estimate == 0.0 else iv.format()


def _value(v: Any) -> str:
    return f"{v:.3g}" if isinstance(v, float) else str(v)


def sensitivity_lines(head: dict, variation_rows: list[dict], preset: Any) -> list[str]:
    """Markdown: the headline ratio, then per assumed number its range, reason and the ratio at each end; the
    joint draws' range."""
    sens = [r for r in variation_rows if r.get("variation") == "sensitivity"]
    if not sens:
        return []
    _, ref = pixel_ratio(head)
    lines = [f"The {EMULATORS[BASELINE].label}/{EMULATORS[CANDIDATE].label} flicker ratio at the pixels, headline "
             f"run: {ref}. Each number the `{preset.name}` preset marks assumed, at each end of its plausible range "
             f"(one at a time, {sens[0]['repeats']} repeats on the headline run's seeds):", "",
             "| assumed number | preset | plausible range | why | ratio at the ends |",
             "| --- | --- | --- | --- | --- |"]
    for key in dict.fromkeys(r["variation_key"] for r in sens):
        entry = preset.assumed[key]
        span = f"{_value(entry.low)} - {_value(entry.high)}" if not entry.values else ", ".join(map(str, entry.values))
        ends = "; ".join(f"{r['variation_end']}: {pixel_ratio(r)[1]}" for r in sens if r["variation_key"] == key)
        lines.append(f"| `{key}` | {_value(entry.value)} | {span} | {entry.why} | {ends} |")
    joint = [pixel_ratio(r)[0] for r in variation_rows if r.get("variation") == "joint"]
    values = [iv.estimate for iv in joint if iv is not None and math.isfinite(iv.estimate)]
    if values:
        lines += ["", f"All of them drawn at once ({len(values)} draw{'s' if len(values) > 1 else ''}, uniform in "
                      f"their ranges): ratio estimate {min(values):.3g} to {max(values):.3g}."]
    return lines


def _unchanged(row: dict, head: dict, emulator: str) -> bool:
    """Whether a run on the headline's seeds made, in every repeat, exactly the headline's events of a stream
    (its setting does not act on that stream)."""
    key = f"{emulator}_pixel_events_per_repeat"
    mine, theirs = row.get(key), head.get(key)
    return mine is not None and theirs is not None and row is not head and mine == theirs[:len(mine)]


def points(rows: list[dict]) -> list[Point]:
    """The headline pair's points of each row (the headline, ``rows[0]``, first); a stream that a setting does
    not change (the same events on the same seeds) appears only with the headline."""
    out: list[Point] = []
    for row in rows:
        setting = row.get("variation_key") if row.get("variation") == "tradeoff" else HEADLINE_SETTING
        for e in HEADLINE:
            if _unchanged(row, rows[0], e):
                continue
            flicker = interval_of(row, f"{e}_pixel_flicker_per_pixel_s")
            noise = interval_of(row, f"{e}_pixel_noise_per_pixel_s")
            if flicker is None or noise is None:
                continue
            scored = [(row[f"{m}_ssim"], m) for m, entry in METHODS.items() if entry.emulator == e
                      and np.isfinite(row.get(f"{m}_ssim", np.nan))]
            ssim, method = max(scored) if scored else (float("nan"), "-")
            p = Point(e, str(setting), flicker, noise, row[f"{e}_pixel_events_per_pixel_s"],
                      row[f"{e}_events_per_s"] / row["pixels"], float(ssim), method, bool(row.get(f"{e}_bus_limited")))
            out.append(p)
    return out


def wins(pts: list[Point]) -> list[tuple[Point, Point]]:
    """(gradient, DVS) pairs where the gradient setting makes fewer flicker- and fewer noise-induced events
    than the DVS setting (intervals apart) and no more events in all (at the same bandwidth or less)."""
    grads = [p for p in pts if p.emulator == CANDIDATE]
    dvs = [p for p in pts if p.emulator == BASELINE]
    return [(g, d) for g in grads for d in dvs if g.flicker.high < d.flicker.low and g.noise.high < d.noise.low
            and g.made <= d.made]


def tradeoff_lines(pts: list[Point], cap: float | None) -> list[str]:
    """Markdown: the verdict (the winning settings, or why none wins), then one table line per point."""
    if len({p.setting for p in pts}) < 2:
        return []
    won = wins(pts)
    grads = [p for p in pts if p.emulator == CANDIDATE]
    dvs = [p for p in pts if p.emulator == BASELINE]
    if won:
        verdict = ("Gradient events beat DVS on flicker and on noise at no more bandwidth at: "
                   + "; ".join(f"gradient with {g.setting} against DVS with {d.setting}" for g, d in won) + ".")
    elif grads and dvs:
        quiet = min(grads, key=lambda p: p.noise.estimate)
        loud = max(dvs, key=lambda p: p.noise.estimate)
        verdict = (f"At none of these settings do gradient events beat DVS on both flicker and noise: the quietest "
                   f"gradient setting ({quiet.setting}) still makes {_rate(quiet.noise)} noise-induced ev/px/s "
                   f"against DVS's {_rate(loud.noise)} at its noisiest ({loud.setting}). The gradient comparators "
                   "switch on differences of neighbouring pixels' noisy outputs at thresholds below DVS's, so "
                   "noise crosses them far more often.")
    else:
        return []
    cap_text = f"; the bus delivers at most {cap:.3g} ev/px/s" if cap else ""
    lines = [verdict, "", f"Rates in ev/px/s at the pixels, before the bus{cap_text}:", "",
             "| stream | setting | flicker-induced | noise-induced | made | delivered | best SSIM |",
             "| --- | --- | --- | --- | --- | --- | --- |"]
    for p in pts:
        delivered = f"{p.delivered:.3g}" + (" (at the bus cap)" if p.at_cap else "")
        ssim = f"{p.ssim:.3f} ({p.method})" if np.isfinite(p.ssim) else "-"
        lines.append(f"| {EMULATORS[p.emulator].label} | {p.setting} | {_rate(p.flicker)} | {_rate(p.noise)} | "
                     f"{p.made:.3g} | {delivered} | {ssim} |")
    return lines
