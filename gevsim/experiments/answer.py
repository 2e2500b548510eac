"""The report's answer: three sentences about the headline run, its range over the assumed numbers, and where
gradient events win (issue 35).

The answer is about the pixels: the DVS and gradient flicker-induced rates the pixels made (before the bus) and
their ratio with its interval, with the ratio's range over the ``[sensitivity]`` runs; then what the bus
delivers (a stream at the cap is said to be at it, filled by flicker, noise or both, never quoted as a flicker
or noise rate); then reconstruction. At most :data:`MAX_WORDS` words.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from gevsim.emulation.emulators import EMULATORS, HEADLINE
from gevsim.evaluation.methods import METHODS
from gevsim.experiments.aggregate import interval_of, row_methods
from gevsim.metrics.attribution import Interval

BASELINE, CANDIDATE = HEADLINE
#: The answer's length limit (issue 35: a person reads it in one minute).
MAX_WORDS = 80


def _g(v: float) -> str:
    """A number to 3 significant digits without an exponent below a million: 1380, 30.4, 0.0123."""
    return f"{float(f'{v:.3g}'):g}" if abs(v) < 1e6 else f"{v:.3g}"


def rate_text(iv: Interval) -> str:
    """An interval as the answer writes it: "1380 [1370, 1390]", or "not distinguishable from zero (...)"."""
    text = f"{_g(iv.estimate)} [{_g(iv.low)}, {_g(iv.high)}]"
    return f"not distinguishable from zero ({text})" if iv.includes_zero else text


def headline_row(rows: list[dict], study: Any) -> dict:
    """The row of the run the answer is about (``[report] headline``; the first run when not given)."""
    want = study.headline or {}
    return next((r for r in rows if all(r.get(k) == v for k, v in want.items())), rows[0])


def rate_level(row: dict) -> str:
    """The prefix of a row's rates at the pixels ("pixel_"), or "" (what the bus delivered) where its records
    did not keep what the pixels made."""
    return "pixel_" if f"{CANDIDATE}_pixel_flicker_per_pixel_s" in row else ""


def pixel_ratio(row: dict) -> tuple[Interval | None, str]:
    """The DVS/gradient ratio of flicker-induced rates at the pixels (the bus's where the pixels' were not
    kept): its interval and its text ("45.3 [42.5, 48.5]", "at least 18.2", ...)."""
    level = rate_level(row)
    iv = interval_of(row, f"{level}flicker_rejection_ratio")
    if iv is None:
        return None, "not measured"
    if math.isfinite(iv.low) and math.isfinite(iv.high):
        return iv, rate_text(iv)
    bound = row.get(f"{level}flicker_rejection_ratio_at_least")
    return iv, (f"at least {bound:.3g}" if bound else "not determined")


def ratio_range(head: dict, variation_rows: list[dict]) -> tuple[float, float, str] | None:
    """(lowest, highest) ratio estimate over the headline and its sensitivity runs, and the assumed number
    that moves it most; None without sensitivity runs."""
    sens = [r for r in variation_rows if r.get("variation") in ("sensitivity", "joint")]
    values = [(v.estimate, r) for r in [head] + sens if (v := pixel_ratio(r)[0]) is not None
              and math.isfinite(v.estimate) and v.estimate > 0]
    if len(values) < 2:
        return None
    spans: dict[str, list[float]] = {}
    for value, r in values:
        if r.get("variation") == "sensitivity":
            spans.setdefault(r["variation_key"], []).append(value)
    ref = values[0][0]
    most = max(spans, key=lambda k: max(max(v / ref, ref / v) for v in spans[k])) if spans else ""  # the widest
    return min(v for v, _ in values), max(v for v, _ in values), most


def _filled_by(row: dict, emulator: str) -> str:
    """What fills a bus-limited stream: flicker, noise or both (each compared alone with the cap)."""
    cap = row.get("bus_cap_per_pixel_s") or float("inf")
    flicker = row.get(f"{emulator}_pixel_flicker_per_pixel_s", 0.0)
    noise = row.get(f"{emulator}_pixel_noise_per_pixel_s", 0.0)
    if flicker >= cap and noise >= cap:
        return "both flicker and noise"
    return "flicker" if flicker >= cap else "noise" if noise >= cap else "flicker and noise together"


def bus_sentence(row: dict, sensor: str) -> str:
    """What the sensor's bus delivers of the headline pair: all of it, or which stream is at the cap and why."""
    cap = row.get("bus_cap_per_pixel_s")
    limited = [e for e in HEADLINE if row.get(f"{e}_bus_limited")]
    if cap is None:
        return "The readout is not rate-limited (the preset gives no bus cap)."
    if not limited:
        return f"The {sensor} bus (at most {_g(cap)} ev/px/s) delivers all of both streams."
    parts = [f"{EMULATORS[e].label} with {_filled_by(row, e)}" for e in limited]
    noise = interval_of(row, f"{CANDIDATE}_pixel_noise_per_pixel_s")
    tail = f" ({EMULATORS[CANDIDATE].label} noise {rate_text(noise)} ev/px/s)" if noise and CANDIDATE in limited else ""
    return f"The {sensor} bus delivers at most {_g(cap)} ev/px/s: {' and '.join(parts)} fill it{tail}."


def quality_sentence(rows: list[dict]) -> str:
    """The best reconstruction of each stream (mean SSIM over ``rows``: the headline's), or ""."""
    best: dict[str, tuple[float, str]] = {}
    for m in row_methods(rows, scored=True):
        kind = EMULATORS[METHODS[m].emulator].label
        mean = float(np.nanmean([r.get(f"{m}_ssim", np.nan) for r in rows]))
        if np.isfinite(mean) and mean > best.get(kind, (-2.0, ""))[0]:
            best[kind] = (mean, m)
    if len(best) < 2:
        return ""
    texts = [f"{k} {v:.3f} ({m}{' with APS frames' if METHODS[m].needs_aps else ''})" for k, (v, m) in best.items()]
    return "Best reconstruction SSIM: " + ", ".join(texts) + "."


def answer(rows: list[dict], study: Any, variation_rows: list[dict], sensor: str) -> list[str]:
    """The opening answer: at most three sentences and :data:`MAX_WORDS` words."""
    head = headline_row(rows, study)
    rates = [interval_of(head, f"{e}_pixel_flicker_per_pixel_s") or interval_of(head, f"{e}_flicker_per_pixel_s")
             for e in HEADLINE]
    if rates[0] is None or rates[1] is None:
        return []
    _, ratio = pixel_ratio(head)
    render = study.base.get("render", {})
    width, height = head.get("window") or (render.get("width", "?"), render.get("height", "?"))  # a swept window
    size = f"{width}x{height}"
    where = (f"a {size} window at the chip's pitch" if study.base.get("footprint") == "chip" else
             f"the scene at {size}")
    lamp = f"{head['flicker_frequency_hz']:g} Hz {head['flicker_group']}" if head.get("flicker_frequency_hz") \
        else head["flicker_group"]
    spread = ratio_range(head, variation_rows)
    moves = f" (estimate {_g(spread[0])}-{_g(spread[1])} over the assumed numbers)" if spread else ""
    first = (f"At the pixels of a {sensor} ({where}; {head.get('scene', study.base['scene'])}, {lamp}), "
             f"{EMULATORS[BASELINE].label} makes {rate_text(rates[0])} flicker-induced ev/px/s and "
             f"{EMULATORS[CANDIDATE].label} {rate_text(rates[1])}: ratio {ratio}{moves}.")
    return [s for s in (first, bus_sentence(head, sensor), quality_sentence([head])) if s]


def words(sentences: list[str]) -> int:
    """Words of the answer, as a reader counts them (whitespace-separated)."""
    return sum(len(s.split()) for s in sentences)
