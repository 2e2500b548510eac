"""Study outputs: results table (CSV, JSON), per-pixel maps, PNG figures and one Markdown report,
written into a staged folder and renamed into place together with the config.

Every flicker-induced rate and the rejection ratio appear with their 95 % interval; an estimate
whose interval holds zero is written "not distinguishable from zero (...)", never as a bare number
(:meth:`gevsim.metrics.attribution.Interval.format`).
"""

from __future__ import annotations

import csv
import io
import json
import math
from pathlib import Path

import numpy as np

import gevsim
from gevsim.emulation.emulators import EMULATORS, HEADLINE
from gevsim.evaluation.methods import METHODS
from gevsim.experiments import study_plots
from gevsim.experiments.aggregate import agreement, interval_of, pixel_level_text, row_emulators, row_methods
from gevsim.experiments.study import Study, run_id

BASELINE, CANDIDATE = HEADLINE  # the pair the report compares (baseline over candidate: DVS, gradient)
BASE_LABEL, CAND_LABEL = EMULATORS[BASELINE].label, EMULATORS[CANDIDATE].label


def flat_rows(rows: list[dict]) -> list[dict]:
    """Rows without nested values (spectra), lists as strings: one CSV line per run."""
    return [{k: (json.dumps(v) if isinstance(v, list) else v) for k, v in row.items() if not isinstance(v, dict)}
            for row in rows]


def write_table(folder: Path, rows: list[dict]) -> None:
    flat = flat_rows(rows)
    keys = list(dict.fromkeys(k for row in flat for k in row))
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=keys)
    writer.writeheader()
    writer.writerows(flat)
    (folder / "results.csv").write_text(buffer.getvalue())
    (folder / "results.json").write_text(json.dumps(rows, indent=1, default=float))


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


def _label(row: dict, study: Study) -> str:
    return ", ".join(f"{a}={row.get(a)}" for a in study.axes)


def answer(rows: list[dict], study: Study) -> list[str]:
    """The report's opening answer, three sentences: which sensor rejects which flicker by how much,
    and what it costs in noise events and reconstruction quality, with intervals."""
    if "flicker_rejection_ratio" not in rows[0]:
        return []
    scenes = list(dict.fromkeys(r.get("scene", study.base["scene"]) for r in rows))
    parts = []
    for scene in scenes:
        sel = [r for r in rows if r.get("scene", study.base["scene"]) == scene]
        best = max(sel, key=lambda r: r[f"{BASELINE}_flicker_per_pixel_s_low"])  # the clearest flicker
        lamp = best["flicker_group"] + (f" at {best['flicker_frequency_hz']:g} Hz" if best["flicker_frequency_hz"]
                                        else " (steady)")
        where = ", ".join(f"{a}={best.get(a)}" for a in study.axes if a != "scene")
        parts.append(f"in {scene} ({lamp}; {where}) {BASE_LABEL} events carry "
                     f"{fmt(best, f'{BASELINE}_flicker_per_pixel_s')} flicker-induced ev/px/s and {CAND_LABEL} "
                     f"events {fmt(best, f'{CANDIDATE}_flicker_per_pixel_s')}, a rejection ratio of {ratio_text(best)}")
    first = (f"{CAND_LABEL[:1].upper()}{CAND_LABEL[1:]} events against {BASE_LABEL}, 95 % intervals over repeated "
             "noise seeds: " + "; ".join(parts) + ".")
    noise = {e: float(np.median([r[f"{e}_noise_per_pixel_s"] for r in rows])) for e in HEADLINE}
    worst = max(rows, key=lambda r: r[f"{CANDIDATE}_noise_per_pixel_s"])
    second = (f"The cost in noise: the median noise-induced rate is {noise[CANDIDATE]:.3g} ev/px/s for {CAND_LABEL} "
              f"events against {noise[BASELINE]:.3g} for {BASE_LABEL}, up to "
              f"{fmt(worst, f'{CANDIDATE}_noise_per_pixel_s')} ({_label(worst, study)}).")
    third = ""
    methods = row_methods(rows, scored=True)
    by_stream: dict[str, list[str]] = {}
    for m in methods:
        by_stream.setdefault(EMULATORS[METHODS[m].emulator].kind, []).append(m)
    if len(by_stream) == 2:
        texts = []
        for stream, ms in by_stream.items():
            best_m = max(ms, key=lambda m: np.nanmean([r[f"{m}_ssim"] for r in rows]))
            mean = float(np.nanmean([r[f"{best_m}_ssim"] for r in rows]))
            texts.append(f"{stream} events {mean:.3f} ({best_m})")
        third = ("In reconstruction quality (SSIM against the flicker-free scene, mean over runs) the best method "
                 f"reaches {' and '.join(texts)}; per-run intervals are in the table below.")
    return [first, second] + ([third] if third else [])


def findings(rows: list[dict], study: Study) -> list[str]:
    """Plain-language sentences, each figure with its interval."""
    out = []
    emulators = row_emulators(rows)
    for row in rows:
        cells = [f"{EMULATORS[e].label} {fmt(row, f'{e}_flicker_per_pixel_s')}" for e in emulators]
        out.append(f"{_label(row, study)}: flicker-induced ev/px/s " + ", ".join(cells)
                   + f"; rejection ratio {ratio_text(row)}.")
    disagreements = [f"{_label(r, study)}: {text}" for r in rows for e in emulators
                     if (text := agreement(r, e))]
    checked = sum(1 for r in rows for e in emulators if f"{e}_phase_locked_per_pixel_s" in r)
    if checked:
        if disagreements:
            out.append(f"**The two estimators disagree** in {len(disagreements)} of {checked} (run, stream) pairs "
                       "on whether flicker acts: " + "; ".join(disagreements) + ".")
        else:
            out.append(f"The phase-locked estimator (no subtraction) and the counterfactual agree on whether flicker "
                       f"acts in all {checked} (run, stream) pairs where both were made.")
        leaks = [(r, e) for r in rows for e in emulators
                 if r.get(f"{e}_phase_locked_control_per_pixel_s_low", 0.0) > 0]
        if leaks:
            out.append(f"In {len(leaks)} (run, stream) pairs the flicker-free counterfactual itself shows a rate "
                       "modulation at the lamp's harmonics (scene motion or pose changes at those frequencies): "
                       "there the phase-locked figure is an upper estimate.")
    if "hysteresis_ln" in rows[0]:
        for h in sorted({r["hysteresis_ln"] for r in rows}):
            sel = [r[f"{CANDIDATE}_noise_per_pixel_s"] for r in rows if r["hysteresis_ln"] == h]
            out.append(f"With hysteresis {h} ln: {CAND_LABEL} noise-induced rate {np.median(sel):.3g} ev/px/s "
                       "(median over runs).")
    return out


def map_findings(rows: list[dict]) -> list[str]:
    """Where flicker events come from: shares at lamp-region borders and in the dimmest quarter."""
    out = []
    for e in [e for e in row_emulators(rows) if EMULATORS[e].kind in {EMULATORS[h].kind for h in HEADLINE}]:
        sel = [r for r in rows if r.get(f"{e}_flicker_border_share") is not None
               and (iv := interval_of(r, f"{e}_flicker_per_pixel_s")) is not None and iv.low > 0]
        if not sel:
            continue
        border = np.median([r[f"{e}_flicker_border_share"] for r in sel])
        dim = np.median([r[f"{e}_flicker_dim_share"] for r in sel])
        area_b = np.median([r["border_area_share"] for r in sel])
        area_d = np.median([r["dim_area_share"] for r in sel])
        out.append(f"{EMULATORS[e].label}: in the {len(sel)} runs where flicker adds events beyond their interval, "
                   f"{_share(border)} lie at borders between regions lit by different lamps "
                   f"({100 * area_b:.0f} % of the pixels: {_concentration(border, area_b)}) and {_share(dim)} "
                   f"in the dimmest quarter of the pixels ({_concentration(dim, area_d)}; medians over runs).")
    return out


def _share(share: float) -> str:
    """A region's share of the flicker-induced events, in words where it is not positive: a difference of
    counts (with flicker minus without) is negative where flicker removes events there (the noise and flicker
    events interact: a pixel busy with flicker, or held in reset, fires fewer noise events)."""
    if share > 0.005:
        return f"{100 * share:.0f} % of them"
    if share >= -0.005:
        return "none of them"
    return "none of them (flicker removes events there: fewer than without it)"


def _concentration(share: float, area: float) -> str:
    if area <= 0:
        return "no such pixels"
    if share <= 0:
        return "none there"
    ratio = share / area
    if ratio >= 1.5:
        return f"{ratio:.2g}x their share of the image: concentrated there"
    if ratio <= 1 / 1.5:
        return f"{ratio:.2g}x their share of the image: fewer there than elsewhere"
    return f"{ratio:.2g}x their share of the image: not concentrated there"


def render_floor_findings(rows: list[dict]) -> list[str]:
    """Sentences on render quality: the achieved noise and where flicker rates sit near their floor."""
    if "render_se_ln" not in rows[0]:
        return []
    worst = max(r["render_se_ln"] for r in rows)
    spp = sorted({r["render_spp_min"] for r in rows} | {r["render_spp_max"] for r in rows})
    out = [f"**Render quality:** {spp[0]}-{spp[-1]} samples per pixel; worst p{rows[0]['render_se_percentile']:g} "
           f"standard error of the flicker-relevant ln radiance {worst:.3g}."]
    missed = [r for r in rows if r.get("render_target_ln") is not None and not r["render_target_reached"]]
    if missed:
        out.append(f"{len(missed)} of {len(rows)} runs stopped short of the noise target (max_spp or time budget).")
    close = []
    for e in row_emulators(rows):
        n = sum(1 for r in rows if r[f"{e}_render_floor_per_pixel_s"] > 0.2 * abs(r[f"{e}_flicker_per_pixel_s"]))
        if n:
            close.append(f"{e} in {n}")
    if close:
        out.append("The render-noise floor (events render noise alone causes) exceeds 20 % of the flicker-induced "
                   f"rate for {', '.join(close)} of {len(rows)} runs: there the figure is set partly by the "
                   "renderer; render to a smaller noise_target_ln before drawing conclusions.")
    else:
        out.append("Every flicker-induced rate is at least 5x its render-noise floor: render noise does not decide "
                   "these figures.")
    return out


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


METHOD_TEXT = (
    "How the numbers are made. Each run is repeated with R noise seeds (seed, seed + 1, ...). Each repeat is "
    "emulated four times with the same seed (common random numbers): as is, with each lamp at its mean (no "
    "flicker), with an ideal pixel as well, and the render-noise floor (ideal pixel, lamps at their mean, the "
    "rendered images' Monte Carlo error redrawn at the lamp frequency). Per repeat, flicker-induced = run minus "
    "no-flicker, noise-induced = no-flicker minus ideal, render-noise floor = floor run minus ideal; the figures "
    "are their means over repeats with 95 % Student t intervals. The rejection ratio is the ratio of the "
    f"{BASE_LABEL} and {CAND_LABEL} mean flicker-induced rates with Fieller's 95 % interval from the paired repeats "
    f"(where the {CAND_LABEL} rate is not distinguishable from zero Fieller's set is unbounded, and a one-sided "
    f"lower bound is given: the {BASE_LABEL} interval's low end over the {CAND_LABEL} interval's high end, or over "
    "3 events in all repeats when none was counted). The phase-locked estimate needs no subtraction: the event "
    "times of all repeats are folded on "
    "the lamp period and the RMS of the rate modulation carried by the first 4 harmonics is measured, Poisson "
    "bias removed, with a bootstrap interval and a p-value against uniform phases; the same statistic of the "
    "flicker-free counterfactual is its control. It measures the lamp-locked part of the rate, not its mean, so "
    "the two estimators are compared by what they detect. Reconstructions are scored with EVREAL's MSE/SSIM "
    "against the flicker-free log irradiance.")


def event_strips(out: Path, study: Study, rows: list[dict]) -> list[tuple[str, str]]:
    """(path relative to ``out``, caption) of the event strips of repeat 0
    (:func:`gevsim.experiments.repeat.event_strip`), one per distinct (``[report] lines``, ``x``) value:
    what each emulator made of the last flicker period, beside the ground truth."""
    from gevsim.experiments.repeat import finished_repeat

    keys = [k for k in (study.report.get("lines"), study_plots.x_axis(study)) if k]
    seen, strips = set(), []
    for row in rows:
        which = tuple(row.get(k) for k in keys)
        record = finished_repeat(out, row["id"], 0) or {}
        strip = record.get("strip")
        if which in seen or not strip or not (out / "runs" / row["id"] / strip["file"]).exists():
            continue
        seen.add(which)
        period = f"one period of {row['flicker_group']} ({row['flicker_frequency_hz']:g} Hz)" \
            if row.get("flicker_frequency_hz") else "the run's end (steady light)"
        caption = (f"{_label(row, study)}, seed {row['seeds'][0]}: events over {period}, in windows of "
                   f"{strip['window_us'] / 1000:g} ms from t = {strip['start_us'] / 1000:g} ms (one row each). "
                   "DVS/CSDVS: ON blue, OFF red; gradient: X steps in red, Y in green, up brighter and down darker "
                   "than grey; right: the ground-truth log irradiance.")
        strips.append((f"runs/{row['id']}/{strip['file']}", caption))
    return strips


def write_report(folder: Path, study: Study, rows: list[dict], made: list, maps_made: list,
                 strips: list | None = None) -> None:
    n_rep = rows[0]["repeats"]
    parts = [f"# Study: {study.name}", "", study.description, ""]
    head = [m for m in made if m[0] == "headline.png"]
    for name, caption in head:
        parts += [f"![{caption}]({name})", "", f"*{caption}*", ""]
    parts += ["## Answer", "", " ".join(answer(rows, study)), "",
              f"gevsim {gevsim.__version__}; {len(rows)} runs x {n_rep} repeats; config in `config.toml`, every "
              "number in `results.csv` / `results.json`, per-pixel maps in `maps.npz`.", "", "## Findings", ""]
    parts += [f"- {s}" for s in findings(rows, study) + render_floor_findings(rows)]
    parts += ["", METHOD_TEXT, ""]
    for name, caption in made:
        if name != "headline.png":
            parts += [f"![{caption}]({name})", "", f"*{caption}*", ""]
    if strips:
        parts += ["## What the sensors see", ""]
        for name, caption in strips:
            parts += [f"![{caption}]({name})", "", f"*{caption}*", ""]
    if maps_made:
        parts += ["## Where flicker events come from", ""]
        parts += [f"- {s}" for s in map_findings(rows)] + [""]
        for name, caption in maps_made:
            parts += [f"![{caption}]({name})", "", f"*{caption}*", ""]
    parts += ["## Runs", "", key_table(rows, study), ""]
    (folder / "report.md").write_text("\n".join(parts))


def write_maps(folder: Path, study: Study, out: Path, rows: list[dict]) -> dict[str, dict]:
    """Every run's maps (from ``runs/<id>/maps.npz``) into one ``maps.npz``, keys ``<run id>/<name>``."""
    collected, flat = {}, {}
    for row in rows:
        with np.load(out / "runs" / row["id"] / "maps.npz") as data:
            collected[row["id"]] = {k: data[k] for k in data.files}
        flat.update({f"{row['id']}/{k}": v for k, v in collected[row["id"]].items()})
    with open(folder / "maps.npz", "wb") as fh:
        np.savez_compressed(fh, **flat)
    return collected


def write_study_outputs(out: str | Path, study: Study, rows: list[dict]) -> Path:
    """results.csv/json, maps.npz, figures, report.md and config.toml, staged then moved in next to ``runs/``."""
    import os

    from gevsim.io import Staged
    from gevsim.plots import _pyplot

    out = Path(out)
    assert all(row["id"] == run_id(study, p) for row, p in zip(rows, study.runs()))
    staged = Staged(out / "outputs-partial", folder=True)  # locked while it exists; a killed run's is swept
    stage = staged.path
    try:
        write_table(stage, rows)
        maps = write_maps(stage, study, out, rows)
        plt = _pyplot()
        made = [m for m in (study_plots.headline(stage, study, rows, plt), study_plots.rates(stage, study, rows, plt),
                            study_plots.quality(stage, study, rows, plt), study_plots.spectrum(stage, study, rows, plt),
                            study_plots.pareto(stage, rows, plt)) if m]
        maps_made = [study_plots.flicker_maps(stage, study, row, maps[row["id"]], k, plt) for k, row in enumerate(rows)]
        write_report(stage, study, rows, made, maps_made, event_strips(out, study, rows))
        (stage / "config.toml").write_text(study.text)
        for old in out.glob("maps_*.png"):  # an earlier report's panels (the study may have fewer runs now)
            old.unlink()
        for item in stage.iterdir():
            os.replace(item, out / item.name)
    finally:
        staged.discard()
    return out / "report.md"


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
