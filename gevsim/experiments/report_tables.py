"""The report's tables: every run's figures with their intervals (``report.md``'s table, and the table
``gevsim study`` prints), and the cells they are made of."""

from __future__ import annotations

import math

import numpy as np

from gevsim.emulation.emulators import EMULATORS, HEADLINE
from gevsim.evaluation.methods import METHODS
from gevsim.experiments.aggregate import interval_of, pixel_level_text, row_emulators, row_methods
from gevsim.experiments.study import Study

BASELINE, CANDIDATE = HEADLINE  # the pair the report compares (baseline over candidate: DVS, gradient)
BASE_LABEL, CAND_LABEL = EMULATORS[BASELINE].label, EMULATORS[CANDIDATE].label


def _label(row: dict, study: Study) -> str:
    return ", ".join(f"{a}={row.get(a)}" for a in study.axes)


def flicker_cell(row: dict, emulator: str, what: str = "flicker") -> str:
    """An emulator's flicker- (or noise-) induced rate, marked where the readout limited the stream (the
    difference of two runs then measures the bus, not the pixels)."""
    text = fmt(row, f"{emulator}_{what}_per_pixel_s")
    return f"bus-limited: {text}" if row.get(f"{emulator}_bus_limited") else text


def fmt(row: dict, key: str, digits: int = 3) -> str:
    """A row's value with its interval (or the bare value where it has none)."""
    iv = interval_of(row, key)
    if iv is not None and iv.low == iv.high == iv.estimate == 0.0:
        return "0 (in every repeat)"
    if iv is not None:
        return iv.format(digits)
    value = row.get(key)
    return "-" if value is None else f"{value:.{digits}g}"


def ratio_text(row: dict) -> str:
    """The rejection ratio: Fieller's interval, or its one-sided bound where that set is unbounded."""
    iv = interval_of(row, "flicker_rejection_ratio")
    if iv is None:
        return "-"
    limited = [EMULATORS[e].label for e in HEADLINE if row.get(f"{e}_bus_limited")]
    if limited:
        return (f"not measurable on the bus: it limits {' and '.join(limited)} (flicker cannot add events to a "
                f"full bus){pixel_level_text(row)}")
    if math.isfinite(iv.low) and math.isfinite(iv.high):
        return iv.format()
    bound = row.get("flicker_rejection_ratio_at_least")
    if bound:
        ceiling = max(row[f"{CANDIDATE}_flicker_per_pixel_s_high"], 0.0)
        return (f"at least {bound:.3g} (one-sided; the {CAND_LABEL} flicker-induced rate is not distinguishable "
                f"from zero, at most {ceiling:.3g} ev/px/s)")
    return f"not determined ({BASE_LABEL}/{CAND_LABEL} intervals hold zero: Fieller's set is unbounded)"


def key_table(rows: list[dict], study: Study) -> str:
    """Markdown table: the sweep parameters and every headline figure with its 95 % interval."""
    emulators = row_emulators(rows)
    methods = row_methods(rows, scored=True)
    head = (list(study.axes) + [f"{e} flicker ev/px/s" for e in emulators] + [f"{BASE_LABEL}/{CAND_LABEL} ratio"]
            + [f"{e} lamp-locked RMS ev/px/s" for e in emulators if f"{e}_phase_locked_per_pixel_s" in rows[0]]
            + [f"{e} noise ev/px/s" for e in HEADLINE if e in emulators]
            + [f"{m} SSIM" for m in methods] + ["render spp", "render ln error"])
    lines = ["| " + " | ".join(head) + " |", "|" + " --- |" * len(head)]
    for row in rows:
        cells = [str(row.get(a)) for a in study.axes]
        cells += [flicker_cell(row, e) for e in emulators]
        cells += [ratio_text(row)]
        cells += [fmt(row, f"{e}_phase_locked_per_pixel_s") for e in emulators
                  if f"{e}_phase_locked_per_pixel_s" in rows[0]]
        cells += [flicker_cell(row, e, "noise") for e in HEADLINE if e in emulators]
        cells += [fmt(row, f"{m}_ssim") for m in methods]
        cells += [_render_spp(row), _render_error(row)]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def _render_spp(row: dict) -> str:
    if "render_spp_min" not in row:
        return "-"
    lo, hi = row["render_spp_min"], row["render_spp_max"]
    return str(lo) if lo == hi else f"{lo}-{hi}"


def _render_error(row: dict) -> str:
    if "render_se_ln" not in row:
        return "-"
    text = f"p{row['render_se_percentile']:g} {row['render_se_ln']:.3g}"
    if row.get("render_target_ln") is not None:
        text += f" (target {row['render_target_ln']:.3g}{'' if row['render_target_reached'] else ', NOT reached'})"
    return text


def comparison_table(rows: list[dict], study: Study) -> str:
    """Per run and emulator: events/s, flicker-induced and noise-induced events per pixel per second
    with 95 % intervals, and the best reconstruction's SSIM (the demo's table)."""
    lines = []
    for row in rows:
        lines.append(f"\n{_label(row, study)} ({row['repeats']} repeats; {BASE_LABEL}/{CAND_LABEL} {ratio_text(row)})")
        if "render_se_ln" in row:
            lines.append(f"  render: {_render_spp(row)} spp, ln error {_render_error(row)}")
        lines.append(f"  {'emulator':12s} {'events/s':>10s}  {'flicker ev/px/s [95 %]':52s} "
                     f"{'noise ev/px/s [95 %]':52s} {'best recon':>12s} {'SSIM':>6s}")
        for e in EMULATORS:
            if f"{e}_events_per_s" not in row:
                continue
            scored = [m for m, entry in METHODS.items()
                      if entry.emulator == e and f"{m}_ssim" in row and np.isfinite(row[f"{m}_ssim"])]
            best = max(scored, key=lambda m: row[f"{m}_ssim"]) if scored else None
            ssim = f"{row[f'{best}_ssim']:6.3f}" if best else f"{'-':>6s}"
            lines.append(f"  {e:12s} {row[f'{e}_events_per_s']:10.4g}  {flicker_cell(row, e):52s} "
                         f"{flicker_cell(row, e, 'noise'):52s} {best or '-':>12s} {ssim}")
    return "\n".join(lines)
