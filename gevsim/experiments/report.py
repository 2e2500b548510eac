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
from pathlib import Path
from typing import Any

import numpy as np

import gevsim
from gevsim.emulation.emulators import EMULATORS, HEADLINE
from gevsim.experiments import study_plots
from gevsim.experiments.aggregate import agreement, interval_of, row_emulators
from gevsim.experiments.answer import answer, headline_row, pixel_ratio, rate_level
from gevsim.experiments.report_tables import flicker_cell, fmt, key_table, ratio_text  # noqa: F401 (re-exported)
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


def _label(row: dict, study: Study) -> str:
    return ", ".join(f"{a}={row.get(a)}" for a in study.axes)


def findings(rows: list[dict], study: Study) -> list[str]:
    """Plain-language sentences, each figure with its interval."""
    out = []
    emulators = row_emulators(rows)
    for row in rows:
        level = rate_level(row)
        cells = [f"{EMULATORS[e].label} {fmt(row, f'{e}_{level}flicker_per_pixel_s')}" for e in emulators
                 if f"{e}_{level}flicker_per_pixel_s" in row]
        capped = [EMULATORS[e].label for e in emulators if row.get(f"{e}_bus_limited")]
        bus = (f"; at the bus cap ({row['bus_cap_per_pixel_s']:.3g} ev/px/s): {', '.join(capped)}"
               if capped and row.get("bus_cap_per_pixel_s") else "")
        out.append(f"{_label(row, study)}: flicker-induced ev/px/s {'at the pixels ' if level else ''}"
                   + ", ".join(cells) + f"; ratio {pixel_ratio(row)[1]}{bus}.")
    disagreements = [f"{_label(r, study)}: {text}" for r in rows for e in emulators
                     if not r.get(f"{e}_bus_limited") and (text := agreement(r, e))]
    checked = sum(1 for r in rows for e in emulators if f"{e}_phase_locked_per_pixel_s" in r
                  and not r.get(f"{e}_bus_limited"))  # a full bus flattens the rate: no test of the lamp's lock
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
        which = json.dumps([row.get(k) for k in keys], default=str)  # a swept value may be a list (window)
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
                 strips: list | None = None, around: dict | None = None) -> None:
    """report.md: the answer, how far it moves with the assumed numbers and where gradient events win
    (``around``: the answer's sentences and those sections' lines and figures), then the runs, figures, event
    strips and maps."""
    around = around or {}
    n_rep = rows[0]["repeats"]
    parts = [f"# Study: {study.name}", "", study.description, ""]
    figures = dict(around.get("figures", {}))
    parts += ["## Answer", "", " ".join(around.get("answer", [])), "",
              f"gevsim {gevsim.__version__}; {len(rows)} runs x {n_rep} repeats"
              + (f" and {around['variations']} runs around the headline" if around.get("variations") else "")
              + "; config in `config.toml`, every number in `results.csv` / `results.json` (runs around the "
              "headline: `variations.json`), per-pixel maps in `maps.npz`.", ""]
    for title, key in (("How far the answer moves with what was assumed", "sensitivity"),
                       ("Where gradient events win", "tradeoff")):
        if around.get(key):
            parts += [f"## {title}", "", *around[key], ""]
            if key in figures:
                name, caption = figures[key]
                parts += [f"![{caption}]({name})", "", f"*{caption}*", ""]
    parts += ["## Runs", ""]
    parts += [f"- {s}" for s in findings(rows, study) + render_floor_findings(rows)]
    parts += [""]
    for name, caption in made:
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
    parts += ["## Table", "", key_table(rows, study), "", METHOD_TEXT, ""]
    (folder / "report.md").write_text("\n".join(parts))


def around_headline(folder: Path, study: Study, out: Path, rows: list[dict], plt: Any) -> dict:
    """The answer and the sections about the runs around the headline (their rows into ``variations.json``)."""
    from gevsim.experiments import variation_plots as vp
    from gevsim.experiments import variation_report as vr
    from gevsim.experiments.study_run import collect_variations
    from gevsim.pixel import load_preset

    head = headline_row(rows, study)
    preset = load_preset(head.get("sensor", study.base["sensor"]))
    around_rows = collect_variations(study, out)
    (folder / "variations.json").write_text(json.dumps(around_rows, indent=1, default=float))
    pts = vr.points([head] + [r for r in around_rows if r.get("variation") == "tradeoff"])
    figures = {key: fig for key, fig in (("sensitivity", vp.tornado(folder, head, around_rows, plt)),
                                         ("tradeoff", vp.tradeoff(folder, pts, head.get("bus_cap_per_pixel_s"), plt)))
               if fig}
    sentences = answer(rows, study, around_rows, preset.name.upper() if preset.name.startswith("davis") else
                       preset.name)
    return {"answer": sentences, "variations": len(around_rows), "figures": figures,
            "sensitivity": vr.sensitivity_lines(head, around_rows, preset),
            "tradeoff": vr.tradeoff_lines(pts, head.get("bus_cap_per_pixel_s"))}


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
    """results.csv/json, maps.npz, figures, report.md and config.toml, staged then moved in next to ``runs/``
    (under the study folder's lock: what replaces an earlier report is in its mark, :func:`gevsim.io.exclusive`)."""
    from gevsim.io import exclusive

    with exclusive(out, what="study", kind="study"):
        return _write_study_outputs(Path(out), study, rows)


def _write_study_outputs(out: Path, study: Study, rows: list[dict]) -> Path:
    import os

    from gevsim.io import Staged
    from gevsim.plots import _pyplot

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
        around = around_headline(stage, study, out, rows, plt)
        write_report(stage, study, rows, made, maps_made, event_strips(out, study, rows), around)
        (stage / "config.toml").write_text(study.text)
        for old in out.glob("maps_*.png"):  # an earlier report's panels (the study may have fewer runs now)
            old.unlink()
        for item in stage.iterdir():
            os.replace(item, out / item.name)
    finally:
        staged.discard()
    return out / "report.md"


