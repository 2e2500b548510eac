"""A study's figures: every rate and ratio with its 95 % interval, legends outside the data, axes in
physical units, and per-pixel maps of where flicker events come from.

Rates are drawn on a symmetric-log axis, so a negative estimate is drawn where it is, with its
interval, not clamped; a ratio's interval that reaches zero or infinity (Fieller's set unbounded)
is drawn to the edge of the axes with an arrow.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from gevsim.emulation.emulators import EMULATORS
from gevsim.evaluation.methods import METHODS
from gevsim.experiments.aggregate import interval_of, row_emulators, row_methods
from gevsim.experiments.study import Study

#: Physical meaning of sweep axes: axis -> (label, row key giving the plotted value or None for the axis itself).
AXIS_UNITS = {
    "frequency_hz": ("lamp frequency (Hz)", None),
    "light_scale": ("median illuminance on the chip (lux)", "chip_lux_median"),
    "flicker_scale": ("radiance factor of the flickering group", None),
    "duty": ("PWM duty cycle", None),
    "modulation": ("modulation depth", None),
    "thresholds_ln": ("smallest gradient threshold (ln)", None),
    "hysteresis_ln": ("gradient comparator hysteresis (ln)", None),
    "threshold_mismatch_ln": ("threshold mismatch sigma (ln)", None),
    "threshold_on_ln": ("DVS ON threshold (ln)", None),
    "threshold_off_ln": ("DVS OFF threshold (ln)", None),
    "cutoff_hz": ("photoreceptor cutoff (Hz)", None),
    "max_cutoff_hz": ("photoreceptor maximum cutoff (Hz)", None),
    "dark_current_a": ("dark current (A)", None),
    "read_noise_v": ("read noise (V)", None),
    "refractory_s": ("refractory period (s)", None),
}


def x_axis(study: Study) -> str:
    """The swept axis on the x axis: ``[report] x``, else the first sweep axis ("" for none)."""
    return str(study.report.get("x") or next(iter(study.axes), ""))


def axis_label(x: str) -> str:
    """The x axis's label in physical units."""
    return AXIS_UNITS[x][0] if x in AXIS_UNITS else x


def x_value(row: dict, x: str) -> Any:
    """The plotted x value of a row: the physical quantity of the swept axis (e.g. lux for light_scale)."""
    key = AXIS_UNITS.get(x, (x, None))[1]
    value = row.get(key) if key else row.get(x)
    if isinstance(value, list):  # a threshold set: its smallest
        value = min(value)
    return value


def series_labels(study: Study) -> tuple[list[str], Callable[[dict], str]]:
    """The axes other than x that vary (``lines`` first), and a function naming a row's series."""
    x = x_axis(study)
    others = [a for a in study.axes if a != x and len(study.axes[a]) > 1]
    lines = study.report.get("lines")
    if lines in others:
        others.remove(lines)
        others.insert(0, lines)

    def label(row):
        return ", ".join(f"{a}={row.get(a)}" for a in others) if others else study.name

    return others, label


def _xy(rows: list[dict], x: str):
    vals = [x_value(r, x) for r in rows]
    numeric = all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in vals)
    order = sorted(range(len(rows)), key=lambda i: vals[i] if numeric else str(vals[i]))
    return [rows[i] for i in order], ([vals[i] for i in order] if numeric else list(range(len(order)))), \
        numeric, [str(vals[i]) for i in order]


def errorbars(ax: Any, xs: Sequence[float], rows: list[dict], key: str, *, color: str | None = None,
              marker: str = "o", label: str | None = None, offset: float = 1.0, linestyle: str = "-",
              log: bool = True, fill: str = "full") -> Any:
    """Points with their interval (``key``, ``key_low``, ``key_high``); on a log axis, an interval end
    at or below zero or infinite is drawn to the edge with an arrow."""
    ivs = [interval_of(r, key) for r in rows]
    est = np.array([iv.estimate if iv else r.get(key, math.nan) for iv, r in zip(ivs, rows)], float)
    lo = np.array([iv.low if iv else math.nan for iv in ivs], float)
    hi = np.array([iv.high if iv else math.nan for iv in ivs], float)
    x = np.asarray(xs, float) * offset
    face = color if fill == "full" else "none"
    line = ax.plot(x, np.where(np.isfinite(est) & ((est > 0) | (not log)), est, np.nan), marker=marker,
                   linestyle=linestyle, color=color, label=label, markerfacecolor=face)[0]
    color = line.get_color()
    for xi, e, a, b in zip(x, est, lo, hi):
        if not (np.isfinite(a) or np.isfinite(b)) and not np.isfinite(e):
            continue
        a_ok = np.isfinite(a) and (a > 0 or not log)
        b_ok = np.isfinite(b)
        ya = a if a_ok else None
        yb = b if b_ok else None
        if ya is not None and yb is not None:
            ax.plot([xi, xi], [ya, yb], color=color, lw=1.2, alpha=0.8)
        else:  # open-ended: drawn to the edge once the limits are final (open_ends)
            start = ya if ya is not None else (yb if yb is not None else e)
            if start is None or not np.isfinite(start) or (log and start <= 0):
                continue
            ax.__dict__.setdefault("_open_ends", []).append((xi, start, ya is None, yb is None, color))
    return line


def open_ends(ax: Any) -> None:
    """Draw the open ends of intervals (to -inf / +inf, or to <= 0 on a log axis) as lines to the edge
    of the final axes with an arrowhead there."""
    ends = ax.__dict__.pop("_open_ends", [])
    if not ends:
        return
    bottom, top = ax.get_ylim()
    for xi, start, down, up, color in ends:
        for flag, edge, marker in ((down, bottom, "v"), (up, top, "^")):
            if flag:
                ax.plot([xi, xi], [start, edge], color=color, lw=1.0, alpha=0.8)
                ax.plot([xi], [edge], marker=marker, color=color, markersize=6, clip_on=False)
    ax.set_ylim(bottom, top)


def _finish(ax, xlabel, numeric, xs, labels, log_x):
    if numeric and log_x:
        from matplotlib.ticker import NullFormatter

        ax.set_xscale("log")
        ax.xaxis.set_minor_formatter(NullFormatter())
    if not numeric:
        ax.set_xticks(xs, labels, rotation=20)
    ax.set_xlabel(xlabel)
    ax.grid(alpha=0.3, which="both")
    open_ends(ax)


def _log_x(rows, x) -> bool:
    vals = [x_value(r, x) for r in rows]
    vals = [v for v in vals if isinstance(v, (int, float)) and not isinstance(v, bool)]
    return bool(vals) and min(vals) > 0 and max(vals) / min(vals) >= 10


def headline(folder: Path, study: Study, rows: list[dict], plt: Any) -> tuple[str, str] | None:
    """Rejection ratio (DVS / gradient flicker-induced events) with Fieller intervals against the swept axis."""
    if "flicker_rejection_ratio" not in rows[0]:
        return None
    values = [r[k] for r in rows for k in ("flicker_rejection_ratio", "flicker_rejection_ratio_low")
              if np.isfinite(r.get(k, math.nan))]
    if not values:  # every run bus-limited (or without a ratio): nothing to draw
        return None
    x = x_axis(study)
    _, label = series_labels(study)
    groups = list(dict.fromkeys(label(r) for r in rows))
    fig, ax = plt.subplots(figsize=(8.5, 5.6))
    spread = np.geomspace(0.97, 1.03, len(groups)) if len(groups) > 1 and _log_x(rows, x) else np.ones(len(groups))
    symlog = any(v <= 0 for v in values)  # flicker removed gradient events somewhere: show the sign
    numeric, xs, labels = True, [], []
    bound_label: str | None = "lower bound (gradient rate not distinguishable from zero)"
    for k, group in enumerate(groups):
        sel, xs, numeric, labels = _xy([r for r in rows if label(r) == group], x)
        off = spread[k] if numeric else 1.0
        xs_plot = xs if numeric else [v + 0.06 * (k - (len(groups) - 1) / 2) for v in xs]
        line = errorbars(ax, xs_plot, sel, "flicker_rejection_ratio", label=group, offset=off, log=not symlog)
        bounds = [r.get("flicker_rejection_ratio_at_least") for r in sel]
        pts = [(xv * off, b) for xv, b in zip(xs_plot, bounds) if b]
        if pts:
            ax.plot(*zip(*pts), "^", color=line.get_color(), markersize=8, markerfacecolor="none", label=bound_label)
            bound_label = None
    ax.axhline(1.0, color="0.4", lw=0.8, ls="--")
    if symlog:
        ax.set_yscale("symlog", linthresh=0.1)
        ax.axhline(0.0, color="0.2", lw=0.6)
    else:
        ax.set_yscale("log")
    ax.set_ylabel("DVS / gradient flicker-induced events")
    _finish(ax, axis_label(x), numeric, xs, labels, _log_x(rows, x))
    ax.set_title(f"{study.name}: flicker rejection of gradient events\n(95 % Fieller intervals, {rows[0]['repeats']} "
                 "paired repeats; < 0: flicker removes gradient events)", fontsize=10)
    ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.16), ncol=2, borderaxespad=0)
    fig.tight_layout()
    from gevsim.plots import save_figure

    save_figure(fig, folder / "headline.png")
    return ("headline.png", "How many times fewer flicker-induced events gradient events carry than DVS events "
                            "(> 1: gradients reject the flicker), with 95 % intervals (Fieller, paired repeats); "
                            "arrows: the interval is open-ended; triangles: a one-sided lower bound where the "
                            "gradient rate is not distinguishable from zero; dashed: no rejection; runs whose "
                            "readout limits DVS or gradient events have no ratio (not drawn).")


def rates(folder: Path, study: Study, rows: list[dict], plt: Any) -> tuple[str, str]:
    """Flicker-induced events per emulator (counterfactual, filled; phase-locked RMS, open) with
    intervals and the render-noise floor, one panel per series."""
    x = x_axis(study)
    others, label = series_labels(study)
    groups = list(dict.fromkeys(label(r) for r in rows))
    emulators = row_emulators(rows)
    cols = min(4, len(groups))
    nrows = -(-len(groups) // cols)
    fig, axes = plt.subplots(nrows, cols, figsize=(4.4 * cols + 2.6, 3.6 * nrows + 0.8), squeeze=False,
                             sharey=True)
    for ax in axes.ravel()[len(groups):]:
        ax.axis("off")
    log_x = _log_x(rows, x)
    for ax, group in zip(axes.ravel(), groups):
        sel, xs, numeric, labels = _xy([r for r in rows if label(r) == group], x)
        for k, e in enumerate(emulators):
            c = EMULATORS[e].color
            shift = (1.0 + 0.02 * (k - len(emulators) / 2)) if numeric and log_x else 1.0
            errorbars(ax, xs, sel, f"{e}_flicker_per_pixel_s", color=c, label=f"{e} (run - no flicker)", log=False,
                      offset=shift)
            if any(f"{e}_phase_locked_per_pixel_s" in r for r in sel):
                errorbars(ax, xs, sel, f"{e}_phase_locked_per_pixel_s", color=c, marker="s", fill="none",
                          linestyle="none", label=f"{e} lamp-locked RMS", log=False, offset=shift * 1.01)
            floor = [r.get(f"{e}_render_floor_per_pixel_s", math.nan) for r in sel]
            ax.plot(np.asarray(xs, float) * shift, floor, ":", color=c, alpha=0.8, label=f"{e} render-noise floor")
        ax.set_yscale("symlog", linthresh=1.0)
        _finish(ax, axis_label(x), numeric, xs, labels, log_x)
        ax.set_title(group, fontsize=9)
    axes[0, 0].set_ylabel("events / pixel / s")
    handles, names = axes[0, 0].get_legend_handles_labels()
    fig.legend(handles, names, fontsize=7, loc="upper left", bbox_to_anchor=(1.0 - 2.5 / fig.get_figwidth(), 0.95))
    fig.suptitle(f"Flicker-induced event rate, mean of {rows[0]['repeats']} repeats with 95 % intervals\n"
                 "(symmetric log axis: negative estimates drawn where they are)", fontsize=9)
    fig.tight_layout(rect=(0, 0, 1.0 - 2.6 / fig.get_figwidth(), 1))
    from gevsim.plots import save_figure

    save_figure(fig, folder / "flicker_rate.png")
    return ("flicker_rate.png", "Flicker-induced events per pixel per second, mean over repeats with 95 % t "
                                "intervals (filled: run minus its flicker-free counterfactual; open squares: "
                                "RMS of the rate modulation locked to the lamp phase, bootstrap interval, "
                                "no subtraction); dotted: the render-noise floor of the same stream.")


#: Line styles and markers that tell series apart where colour names the method.
SERIES_STYLES: list[tuple[Any, str]] = [(("-", "--", ":", "-.")[k % 4], ("o", "s", "^", "D", "v", "P")[k % 6])
                                        for k in range(12)]


def method_styles(methods: Sequence[str],
                  groups: Sequence[str]) -> tuple[dict[str, str], dict[str, tuple[Any, str]]]:
    """A colour per method (matplotlib's ten cycle colours; gevsim has fewer methods) and a (line style,
    marker) per series (12 distinct pairs, then repeated)."""
    colours = {m: f"C{k % 10}" for k, m in enumerate(methods)}
    styles = {g: SERIES_STYLES[k % len(SERIES_STYLES)] for k, g in enumerate(groups)}
    return colours, styles


def quality(folder: Path, study: Study, rows: list[dict], plt: Any) -> tuple[str, str] | None:
    methods = row_methods(rows)
    if not methods:
        return None
    x = x_axis(study)
    _, label = series_labels(study)
    groups = list(dict.fromkeys(label(r) for r in rows))
    fig, ax = plt.subplots(figsize=(9.5, 4.4))
    numeric, xs, labels = True, [], []
    colours, styles = method_styles(methods, groups)
    for group in groups:
        for m in methods:
            sel, xs, numeric, labels = _xy([r for r in rows if label(r) == group], x)
            if not any(np.isfinite(r[f"{m}_ssim"]) for r in sel):
                continue
            errorbars(ax, xs, sel, f"{m}_ssim", color=colours[m], linestyle=styles[group][0],
                      marker=styles[group][1], log=False)
    ax.set_ylabel("SSIM vs flicker-free reference")
    _finish(ax, axis_label(x), numeric, xs, labels, _log_x(rows, x))
    # Two legends beside the axes: colour = method, line and marker = series (the other swept axes).
    from matplotlib.lines import Line2D

    first = ax.legend([Line2D([], [], color=colours[m], lw=2) for m in methods], methods, title="method",
                      fontsize=8, title_fontsize=8, loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0)
    if len(groups) > 1:
        ax.add_artist(first)
        ax.legend([Line2D([], [], color="0.3", linestyle=styles[g][0], marker=styles[g][1]) for g in groups], groups,
                  title="series", fontsize=7, title_fontsize=8, loc="lower left", bbox_to_anchor=(1.02, 0.0),
                  borderaxespad=0)
    fig.tight_layout()
    from gevsim.plots import save_figure

    save_figure(fig, folder / "quality.png")
    return ("quality.png", "Reconstruction SSIM of each method against the flicker-free reference, mean over "
                           "repeats with 95 % t intervals.")


def spectrum(folder: Path, study: Study, rows: list[dict], plt: Any) -> tuple[str, str] | None:
    with_spec = [row for row in rows if "dvs_spectrum" in row]
    if not with_spec:
        return None
    row = max(with_spec, key=lambda r: r.get("dvs_flicker_per_pixel_s", 0))
    f, amp = np.array(row["dvs_spectrum"]["hz"]), np.array(row["dvs_spectrum"]["amplitude"])
    fig, ax = plt.subplots(figsize=(8, 3.5))
    ax.plot(f, amp, lw=1)
    f0 = row.get("flicker_frequency_hz")
    if isinstance(f0, (int, float)):
        for k in range(1, 6):
            ax.axvline(k * f0, color="0.6", ls=":", lw=1,
                       label=f"flicker harmonics (k x {f0:g} Hz)" if k == 1 else None)
        ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0)
    ax.set_xlabel("frequency (Hz)")
    ax.set_ylabel("DVS event-rate amplitude (events/s)")
    ax.set_title(f"Event-rate spectrum (repeat 0), {', '.join(f'{k}={row[k]}' for k in study.axes if k in row)}",
                 fontsize=10)
    fig.tight_layout()
    from gevsim.plots import save_figure

    save_figure(fig, folder / "spectrum.png")
    return "spectrum.png", "Spectrum of the DVS event rate (first repeat); dotted lines at harmonics of the flicker."


def pareto(folder: Path, rows: list[dict], plt: Any) -> tuple[str, str] | None:
    methods = row_methods(rows)
    stream_of = {m: METHODS[m].emulator for m in methods}
    points = [(row[f"{stream_of[m]}_events_per_s"], row[f"{m}_ssim"], m) for row in rows for m in methods
              if f"{stream_of[m]}_events_per_s" in row and np.isfinite(row[f"{m}_ssim"])]
    if not points:
        return None
    fig, ax = plt.subplots(figsize=(7.5, 4.5))
    for m in methods:
        pts = np.array([(p[0], p[1]) for p in points if p[2] == m])
        if len(pts):
            ax.scatter(np.maximum(pts[:, 0], 1.0), pts[:, 1], s=18, label=m)
    front = pareto_front([(p[0], p[1]) for p in points])
    ax.plot([max(p[0], 1.0) for p in front], [p[1] for p in front], "k--", lw=1, label="Pareto front")
    ax.set_xscale("log")
    ax.set_xlabel("events / s (0 drawn at 1)")
    ax.set_ylabel("SSIM")
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0)
    ax.grid(alpha=0.3, which="both")
    fig.tight_layout()
    from gevsim.plots import save_figure

    save_figure(fig, folder / "pareto.png")
    return ("pareto.png", "Reconstruction quality against bandwidth; the dashed line is the Pareto front "
                          "(fewest events for a given SSIM).")


def pareto_front(points: list[tuple[float, float]]) -> list[tuple[float, float]]:
    """Points not dominated by another with fewer-or-equal events and higher-or-equal quality."""
    front, best = [], -np.inf
    for cost, q in sorted(points, key=lambda p: (p[0], -p[1])):
        if q > best:
            front.append((cost, q))
            best = q
    return front


def flicker_maps(folder: Path, study: Study, row: dict, maps: dict, index: int, plt: Any) -> tuple[str, str]:
    """One run's panel: the scene's chip illuminance, the dominant light group, and each emulator's
    flicker-induced events per pixel (mean over repeats; diverging colours, negative where flicker
    removed events)."""
    from matplotlib.colors import ListedColormap, SymLogNorm

    emulators = [e for e in EMULATORS if f"{e}_flicker_per_pixel_s" in maps]
    n = 2 + len(emulators)
    cols = min(n, 3)
    nrows = -(-n // cols)
    fig, grid = plt.subplots(nrows, cols, figsize=(3.6 * cols, 2.9 * nrows + 0.4), squeeze=False)
    axes = grid.ravel()
    for ax in axes[n:]:
        ax.axis("off")
    axes = axes[:n]
    lux = np.log10(np.maximum(maps["chip_lux"], 1e-9))
    im = axes[0].imshow(lux, cmap="gray", vmin=np.percentile(lux, 1), vmax=np.percentile(lux, 99.5))
    axes[0].set_title("chip illuminance, log10 lux", fontsize=8)
    fig.colorbar(im, ax=axes[0], fraction=0.046)
    names = row.get("group_names", [])
    cmap = ListedColormap(plt.get_cmap("tab10").colors[: max(len(names), 1)])
    im = axes[1].imshow(maps["dominant_group"], cmap=cmap, vmin=-0.5, vmax=len(names) - 0.5, interpolation="nearest")
    axes[1].set_title("dominant light group", fontsize=8)
    bar = fig.colorbar(im, ax=axes[1], fraction=0.046, ticks=range(len(names)))
    bar.ax.set_yticklabels(names, fontsize=7)
    limit = max(max(float(np.abs(maps[f"{e}_flicker_per_pixel_s"]).max()) for e in emulators), 1.0)
    for ax, e in zip(axes[2:], emulators):
        im = ax.imshow(maps[f"{e}_flicker_per_pixel_s"], cmap="RdBu_r",
                       norm=SymLogNorm(linthresh=max(limit * 1e-3, 1.0), vmin=-limit, vmax=limit))
        iv = interval_of(row, f"{e}_flicker_per_pixel_s")
        ax.set_title(f"{e}: {iv.format() if iv else ''}\nflicker ev/px/s", fontsize=7)
        fig.colorbar(im, ax=ax, fraction=0.046)
    for ax in axes:
        ax.set_xticks([])
        ax.set_yticks([])
    fig.suptitle(", ".join(f"{a}={row.get(a)}" for a in study.axes) + f" (flickering group: {row['flicker_group']})",
                 fontsize=9)
    fig.tight_layout()
    from gevsim.plots import save_figure

    name = f"maps_{index:02d}.png"
    save_figure(fig, folder / name)
    caption = (f"Where flicker events come from ({', '.join(f'{a}={row.get(a)}' for a in study.axes)}): chip "
               "illuminance, dominant light group, and flicker-induced events per pixel per second of each stream "
               "(mean of the repeats' run minus no-flicker; red: flicker adds events, blue: removes them).")
    return name, caption
