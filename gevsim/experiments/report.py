"""Study outputs: results table (CSV, JSON), PNG plots and one Markdown report,
written into a staged folder and renamed into place together with the config."""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path

import numpy as np

import gevsim
from gevsim.emulation.emulators import EMULATORS
from gevsim.evaluation.methods import METHODS
from gevsim.experiments.study import Study


def flat_rows(rows: list[dict]) -> list[dict]:
    """Rows without nested values (spectra), lists as strings: one CSV line per run."""
    out = []
    for row in rows:
        out.append({k: (json.dumps(v) if isinstance(v, list) else v) for k, v in row.items()
                    if not isinstance(v, dict)})
    return out


def write_table(folder: Path, rows: list[dict]) -> None:
    flat = flat_rows(rows)
    keys = list(dict.fromkeys(k for row in flat for k in row))
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=keys)
    writer.writeheader()
    writer.writerows(flat)
    (folder / "results.csv").write_text(buffer.getvalue())
    (folder / "results.json").write_text(json.dumps(rows, indent=1, default=float))


def _axis_values(rows, key):
    return [row.get(key) for row in rows]


def plots(folder: Path, study: Study, rows: list[dict]) -> list[tuple[str, str]]:
    """Write the PNG plots; returns (file, caption) pairs for the report."""
    from gevsim.plots import _pyplot, save_figure

    plt = _pyplot()
    x = study.report.get("x") or next(iter(study.axes), None)
    # One panel per combination of the other swept axes (``lines`` first, if given).
    others = [a for a in study.axes if a != x and len(study.axes[a]) > 1]
    lines = study.report.get("lines")
    if lines in others:
        others.remove(lines)
        others.insert(0, lines)
    emulators = [e for e in EMULATORS if f"{e}_flicker_per_pixel_s" in rows[0]]

    def label(row):
        return ", ".join(f"{a}={row.get(a)}" for a in others) if others else study.name

    groups = list(dict.fromkeys(label(row) for row in rows))
    made = []

    def series(group):
        sel = [row for row in rows if label(row) == group]
        return sorted(sel, key=lambda row: (row.get(x) if isinstance(row.get(x), (int, float)) else str(row.get(x))))

    def xvals(sel):
        vals = _axis_values(sel, x)
        numeric = all(isinstance(v, (int, float)) for v in vals)
        return (vals if numeric else list(range(len(vals)))), numeric, [str(v) for v in vals]

    values = [v for v in study.axes.get(x, []) if isinstance(v, (int, float))]
    log_x = bool(values) and min(values) > 0 and max(values) / min(values) >= 10

    # 1. Flicker-induced events per pixel per second, per emulator.
    cols = min(4, len(groups))
    nrows = -(-len(groups) // cols)
    fig, axes = plt.subplots(nrows, cols, figsize=(4.6 * cols, 3.6 * nrows + 0.6), squeeze=False, sharey=True)
    for ax in axes.ravel()[len(groups):]:
        ax.axis("off")
    for ax, group in zip(axes.ravel(), groups):
        sel = series(group)
        xs, numeric, labels = xvals(sel)
        for e in emulators:
            ys = np.maximum([row[f"{e}_flicker_per_pixel_s"] for row in sel], 1e-3)
            ax.plot(xs, ys, "o-", color=EMULATORS[e].color, label=e)
            if f"{e}_render_floor_per_pixel_s" in sel[0]:
                floor = np.maximum([row[f"{e}_render_floor_per_pixel_s"] for row in sel], 1e-3)
                ax.plot(xs, floor, ":", color=EMULATORS[e].color, alpha=0.8, label=f"{e} render-noise floor")
        ax.set_yscale("log")
        if numeric and log_x:
            ax.set_xscale("log")
        if not numeric:
            ax.set_xticks(xs, labels, rotation=20)
        ax.set_xlabel(x)
        ax.set_title(group, fontsize=9)
        ax.grid(alpha=0.3, which="both")
    axes[0, 0].set_ylabel("flicker-induced events / pixel / s")
    axes[0, 0].legend(fontsize=8)
    fig.suptitle("Flicker-induced event rate (run minus its flicker-free counterfactual; <= 0 drawn at 1e-3);\n"
                 "dotted: render-noise floor (what render noise alone causes)", fontsize=10)
    fig.tight_layout()
    save_figure(fig, folder / "flicker_rate.png")
    made.append(("flicker_rate.png", "Flicker-induced events per pixel per second for each emulator; dotted lines: "
                                     "the render-noise floor of the same stream."))

    # 2. Rejection ratio and reconstruction quality.
    methods = [k[:-5] for k in rows[0] if k.endswith("_ssim")]
    fig, (a, b) = plt.subplots(1, 2, figsize=(11, 4))
    for group in groups:
        sel = series(group)
        xs, numeric, labels = xvals(sel)
        if "flicker_rejection_ratio" in sel[0]:
            a.plot(xs, np.maximum([row["flicker_rejection_ratio"] for row in sel], 1e-3), "o-", label=str(group))
        for m in methods:
            b.plot(xs, [row[f"{m}_ssim"] for row in sel], "o-", label=f"{m} ({group})" if others else m)
    for ax, title in ((a, "flicker rejection ratio (DVS / gradient)"), (b, "SSIM vs flicker-free reference")):
        ax.set_xlabel(x)
        ax.set_title(title)
        ax.grid(alpha=0.3, which="both")
        if log_x:
            ax.set_xscale("log")
        ax.legend(fontsize=6)
    a.set_yscale("log")
    fig.tight_layout()
    save_figure(fig, folder / "rejection_quality.png")
    made.append(("rejection_quality.png", "Left: DVS over gradient flicker-induced events. Right: reconstruction "
                                          "SSIM of each method against the flicker-free reference."))

    # 3. Event-rate spectrum of the run with the most flicker events.
    with_spec = [row for row in rows if "dvs_spectrum" in row]
    if with_spec:
        row = max(with_spec, key=lambda r: r.get("dvs_flicker_per_pixel_s", 0))
        f, amp = np.array(row["dvs_spectrum"]["hz"]), np.array(row["dvs_spectrum"]["amplitude"])
        fig, ax = plt.subplots(figsize=(8, 3.5))
        ax.plot(f, amp, lw=1)
        f0 = row.get("flicker_frequency_hz")
        if isinstance(f0, (int, float)):
            for k in range(1, 6):
                ax.axvline(k * f0, color="0.6", ls=":", lw=1)
        ax.set_xlabel("frequency (Hz)")
        ax.set_ylabel("DVS event-rate amplitude (events/s)")
        ax.set_title(f"Event-rate spectrum, {', '.join(f'{k}={row[k]}' for k in study.axes if k in row)}")
        fig.tight_layout()
        save_figure(fig, folder / "spectrum.png")
        made.append(("spectrum.png", "Spectrum of the DVS event rate; dotted lines at harmonics of the flicker."))

    # 4. Quality versus bandwidth, with the Pareto front.
    stream_of = {m: METHODS[m].emulator for m in methods}
    points = [(row[f"{stream_of[m]}_events_per_s"], row[f"{m}_ssim"], m) for row in rows for m in methods
              if f"{stream_of[m]}_events_per_s" in row]
    if points:
        fig, ax = plt.subplots(figsize=(6.5, 4.5))
        for m in methods:
            pts = np.array([(p[0], p[1]) for p in points if p[2] == m])
            ax.scatter(np.maximum(pts[:, 0], 1.0), pts[:, 1], s=18, label=m)
        front = pareto_front([(p[0], p[1]) for p in points])
        ax.plot([max(p[0], 1.0) for p in front], [p[1] for p in front], "k--", lw=1, label="Pareto front")
        ax.set_xscale("log")
        ax.set_xlabel("events / s")
        ax.set_ylabel("SSIM")
        ax.legend(fontsize=8)
        ax.grid(alpha=0.3, which="both")
        fig.tight_layout()
        save_figure(fig, folder / "pareto.png")
        made.append(("pareto.png", "Reconstruction quality against bandwidth; the dashed line is the Pareto front "
                                   "(fewest events for a given SSIM)."))
    return made


def pareto_front(points: list[tuple[float, float]]) -> list[tuple[float, float]]:
    """Points not dominated by another with fewer-or-equal events and higher-or-equal quality."""
    front, best = [], -np.inf
    for cost, quality in sorted(points, key=lambda p: (p[0], -p[1])):
        if quality > best:
            front.append((cost, quality))
            best = quality
    return front


def key_table(rows: list[dict], study: Study) -> str:
    """Markdown table: the sweep parameters and the headline numbers of every run."""
    emulators = [e for e in EMULATORS if f"{e}_flicker_per_pixel_s" in rows[0]]
    methods = [k[:-5] for k in rows[0] if k.endswith("_ssim")]
    head = (list(study.axes) + [f"{e} flicker/px/s (floor)" for e in emulators] + [f"{m} SSIM" for m in methods]
            + ["render spp", "render ln error"])
    lines = ["| " + " | ".join(head) + " |", "|" + " --- |" * len(head)]
    for row in rows:
        cells = [str(row.get(a)) for a in study.axes]
        cells += [f"{row[f'{e}_flicker_per_pixel_s']:.3g} ({_floor(row, e)})" for e in emulators]
        cells += [f"{row[f'{m}_ssim']:.3f}" for m in methods]
        cells += [_render_spp(row), _render_error(row)]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def _floor(row: dict, e: str) -> str:
    v = row.get(f"{e}_render_floor_per_pixel_s")
    return "-" if v is None else f"{v:.3g}"


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
    for e in [k[: -len("_render_floor_per_pixel_s")] for k in rows[0] if k.endswith("_render_floor_per_pixel_s")]:
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


def findings(rows: list[dict]) -> list[str]:
    """Plain-language sentences on what gradient events gain and lose, from the numbers."""
    out = []
    med = {e: float(np.median([r[f"{e}_flicker_per_pixel_s"] for r in rows]))
           for e in EMULATORS if f"{e}_flicker_per_pixel_s" in rows[0]}
    if "dvs" in med and "gradient" in med:
        out.append("Median flicker-induced rate: " + ", ".join(f"{EMULATORS[e].label} {v:.3g}" for e, v in med.items())
                   + " events per pixel per second.")
        flickering = [r for r in rows if r["dvs_flicker_per_pixel_s"] > 1.0]
        if flickering:
            ratio = np.median([r["dvs_flicker_per_pixel_s"] / max(r["gradient_flicker_per_pixel_s"], 1.0)
                               for r in flickering])
            out.append(f"**Gain:** where the flicker reaches the DVS (>1 event/pixel/s, {len(flickering)} of "
                       f"{len(rows)} runs), gradient events carry about {ratio:.3g}x fewer flicker-induced events "
                       "(median ratio). A lamp that dims the whole view shifts every log intensity alike, which "
                       "leaves spatial gradients unchanged; what leaks through comes from borders between regions "
                       "lit by different lamps and from dim pixels whose photoreceptors lag bright ones.")
    if "dvs_noise_per_pixel_s" in rows[0] and "gradient_noise_per_pixel_s" in rows[0]:
        nd = float(np.median([r["dvs_noise_per_pixel_s"] for r in rows]))
        ng = float(np.median([r["gradient_noise_per_pixel_s"] for r in rows]))
        out.append(f"**Cost:** noise-induced rate (median) DVS {nd:.3g}, gradient {ng:.3g} events per pixel per "
                   "second. A gradient comparator whose gradient sits near one of its thresholds toggles with "
                   "the pixel noise; comparator hysteresis (`hysteresis_ln`) and resolution compression cut this, "
                   "the DVS's reset-to-level scheme avoids it.")
        if "hysteresis_ln" in rows[0]:
            for h in sorted({r["hysteresis_ln"] for r in rows}):
                sel = [r["gradient_noise_per_pixel_s"] for r in rows if r["hysteresis_ln"] == h]
                out.append(f"With hysteresis {h} ln: gradient noise-induced rate {np.median(sel):.3g} events per "
                           "pixel per second (median).")
    for m in [k[:-5] for k in rows[0] if k.endswith("_ssim")]:
        scores = [r[f"{m}_ssim"] for r in rows if np.isfinite(r[f"{m}_ssim"])]
        if scores:
            out.append(f"{m}: mean SSIM {np.mean(scores):.3f} against the flicker-free reference "
                       f"({len(scores)} of {len(rows)} runs).")
    out.append("Gradient events need no APS frames to reconstruct a full image (a Poisson solve of the decoded "
               "gradients plus one global level); brightness events alone integrate changes only, so on a mostly "
               "static scene their events-only reconstructions (direct) stay near flat, and the complementary "
               "filter relies on APS frames.")
    return out


def write_report(folder: Path, study: Study, rows: list[dict], made: list) -> None:
    parts = [f"# Study: {study.name}", "", study.description, "",
             f"gevsim {gevsim.__version__}; {len(rows)} runs; config in `config.toml`, every number in "
             "`results.csv` / `results.json`.", "", "## Findings", ""]
    parts += [f"- {s}" for s in findings(rows) + render_floor_findings(rows)]
    parts += ["", "How the numbers are made: every run is emulated four times on the same scene and seed: as is, "
              "with each lamp at its mean (no flicker), with an ideal pixel as well, and the render-noise floor "
              "(ideal pixel, lamps at their mean, the rendered images' Monte Carlo error redrawn at the lamp "
              "frequency). Flicker-induced events = run minus no-flicker; noise-induced = no-flicker minus ideal; "
              "render-noise floor = floor run minus ideal. Reconstructions are scored with "
              "EVREAL's MSE/SSIM against the flicker-free log irradiance.", ""]
    for name, caption in made:
        parts += [f"![{caption}]({name})", "", f"*{caption}*", ""]
    parts += ["## Runs", "", key_table(rows, study), ""]
    (folder / "report.md").write_text("\n".join(parts))


def write_study_outputs(out: str | Path, study: Study, rows: list[dict]) -> Path:
    """results.csv/json, plots, report.md and config.toml, staged then moved in next to ``runs/``."""
    import os
    import shutil
    import tempfile

    out = Path(out)
    stage = Path(tempfile.mkdtemp(prefix=".outputs-partial-", dir=out))
    try:
        write_table(stage, rows)
        made = plots(stage, study, rows)
        write_report(stage, study, rows, made)
        (stage / "config.toml").write_text(study.text)
        for item in stage.iterdir():
            os.replace(item, out / item.name)
    finally:
        shutil.rmtree(stage, ignore_errors=True)
    return out / "report.md"


def comparison_table(rows: list[dict], study: Study) -> str:
    """Per run and emulator: events/s, flicker-induced events per pixel per second and the best
    reconstruction's SSIM/MSE (the demo's table)."""
    lines = []
    for row in rows:
        label = ", ".join(f"{a}={row[a]}" for a in study.axes)
        lines.append(f"\n{label}")
        if "render_se_ln" in row:
            lines.append(f"  render: {_render_spp(row)} spp, ln error {_render_error(row)}")
        lines.append(f"  {'emulator':12s} {'events/s':>11s} {'flicker ev/px/s':>16s} {'render floor':>13s} "
                     f"{'noise ev/px/s':>14s} {'best recon':>14s} {'SSIM':>6s} {'MSE':>7s}")
        for e in EMULATORS:
            if f"{e}_events_per_s" not in row:
                continue
            scored = [m for m, entry in METHODS.items()
                      if entry.emulator == e and f"{m}_ssim" in row and np.isfinite(row[f"{m}_ssim"])]
            best = max(scored, key=lambda m: row[f"{m}_ssim"]) if scored else None
            ssim = f"{row[f'{best}_ssim']:6.3f}" if best else f"{'-':>6s}"
            mse = f"{row[f'{best}_mse']:7.4f}" if best else f"{'-':>7s}"
            lines.append(f"  {e:12s} {row[f'{e}_events_per_s']:11.4g} {row[f'{e}_flicker_per_pixel_s']:16.4g} "
                         f"{_floor(row, e):>13s} {row[f'{e}_noise_per_pixel_s']:14.4g} {best or '-':>14s} {ssim} {mse}")
    return "\n".join(lines)
