"""A study's figures: every rate and ratio with its 95 % interval, legends outside the data, axes in
physical units saying which level a rate is measured at (the pixels, or what the bus delivered), and
per-pixel maps of where flicker events come from.

Rates are drawn on a symmetric-log axis, so a negative estimate is drawn where it is, with its
interval, not clamped; a ratio's interval that reaches zero or infinity (Fieller's set unbounded)
is drawn to the edge of the axes with an arrow. The flicker figures (``flicker_rate.png``,
``headline.png``) are drawn by :mod:`gevsim.experiments.rate_plots`, the shared axes and bus marks by
:mod:`gevsim.experiments.plot_axes`; both are importable from here.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from gevsim.emulation.emulators import EMULATORS
from gevsim.evaluation.methods import METHODS
from gevsim.experiments.aggregate import interval_of, row_methods
from gevsim.experiments.plot_axes import (
    AXIS_UNITS,
    BUS_LIMITED_MARKER,
    BUS_LIMITED_TEXT,
    axis_label,
    bus_caps,
    draw_bus_cap,
    errorbars,
    finish,
    log_x,
    mark_bus_limited,
    method_label,
    number,
    open_ends,
    row_xy,
    series_labels,
    stream_label,
    wrap,
    x_axis,
    x_value,
)
from gevsim.experiments.rate_plots import headline, rates
from gevsim.experiments.study import Study

__all__ = ["AXIS_UNITS", "SERIES_STYLES", "axis_label", "errorbars", "flicker_maps", "headline", "method_styles",
           "open_ends", "pareto", "pareto_front", "quality", "rates", "series_labels", "spectrum", "x_axis",
           "x_value"]

#: Older private names of the shared helpers (now in :mod:`gevsim.experiments.plot_axes`).
_xy, _finish, _log_x = row_xy, finish, log_x

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
    """Reconstruction SSIM of each method against the swept axis; a ring where the bus limited
    the method's stream (it reconstructs from what the bus delivered)."""
    methods = row_methods(rows)
    if not methods:
        return None
    x = x_axis(study)
    _, label = series_labels(study)
    groups = list(dict.fromkeys(label(r) for r in rows))
    fig, ax = plt.subplots(figsize=(10.5, 4.6), layout="constrained")
    numeric, xs, labels = True, list[Any](), list[str]()
    colours, styles = method_styles(methods, groups)
    limited = 0
    for group in groups:
        for m in methods:
            sel, xs, numeric, labels = row_xy([r for r in rows if label(r) == group], x)
            if not any(np.isfinite(r[f"{m}_ssim"]) for r in sel):
                continue
            errorbars(ax, xs, sel, f"{m}_ssim", color=colours[m], linestyle=styles[group][0],
                      marker=styles[group][1], log=False)
            if m in METHODS:
                limited += mark_bus_limited(ax, xs, sel, METHODS[m].emulator, f"{m}_ssim", color=colours[m])
    ax.set_ylabel("SSIM vs flicker-free reference\n(from the delivered events)")
    finish(ax, axis_label(x), numeric, xs, labels, log_x(rows, x))
    # Two legends beside the axes: colour = method, line and marker = series (the other swept axes).
    from matplotlib.lines import Line2D

    handles = [Line2D([], [], color=colours[m], lw=2, label=method_label(m)) for m in methods]
    if limited:
        handles.append(Line2D([], [], color="0.3", linestyle="none", label=BUS_LIMITED_TEXT,
                              **BUS_LIMITED_MARKER))
    fig.legend(handles=handles, title="method (stream)", fontsize=8, title_fontsize=8, loc="outside right upper")
    if len(groups) > 1:
        fig.legend([Line2D([], [], color="0.3", linestyle=styles[g][0], marker=styles[g][1]) for g in groups], groups,
                   title="series", fontsize=7, title_fontsize=8, loc="outside right lower")
    from gevsim.plots import save_figure

    save_figure(fig, folder / "quality.png")
    return ("quality.png", "Reconstruction SSIM of each method against the flicker-free reference, mean over "
                           "repeats with 95 % t intervals; rings: the bus limited the method's stream.")


def spectrum(folder: Path, study: Study, rows: list[dict], plt: Any) -> tuple[str, str] | None:
    """The DVS delivered event rate's spectrum of the run with the most flicker-induced DVS events."""
    with_spec = [row for row in rows if "dvs_spectrum" in row]
    if not with_spec:
        return None
    row = max(with_spec, key=lambda r: r.get("dvs_pixel_flicker_per_pixel_s", r.get("dvs_flicker_per_pixel_s", 0)))
    f, amp = np.array(row["dvs_spectrum"]["hz"]), np.array(row["dvs_spectrum"]["amplitude"])
    fig, ax = plt.subplots(figsize=(8.5, 3.8), layout="constrained")
    ax.plot(f, amp, lw=1, color=EMULATORS["dvs"].color)
    f0 = row.get("flicker_frequency_hz")
    if isinstance(f0, (int, float)):
        for k in range(1, 6):
            ax.axvline(k * f0, color="0.6", ls=":", lw=1,
                       label=f"flicker harmonics (k x {f0:g} Hz)" if k == 1 else None)
        ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0)
    ax.set_xlabel("frequency (Hz)")
    ax.set_ylabel(wrap("DVS delivered event-rate amplitude (events/s)", 30))
    run = ", ".join(f"{k}={row[k]}" for k in study.axes if k in row)
    bus = ("; the bus limited DVS here: this is the spectrum of what it delivered" if row.get("dvs_bus_limited")
           else "")
    ax.set_title(wrap(f"Spectrum of the delivered DVS event rate (repeat 0), {run}{bus}", 85), fontsize=10)
    from gevsim.plots import save_figure

    save_figure(fig, folder / "spectrum.png")
    return ("spectrum.png", "Spectrum of the DVS event rate the bus delivered (first repeat, the run with the most "
                            "flicker-induced DVS events); dotted lines at harmonics of the flicker.")


def _bandwidth(row: dict, stream: str) -> float:
    """A stream's delivered bandwidth: ev/px/s where the row knows its pixels, else events/s."""
    rate = float(row[f"{stream}_events_per_s"])
    return rate / row["pixels"] if row.get("pixels") else rate


def pareto(folder: Path, rows: list[dict], plt: Any) -> tuple[str, str] | None:
    """Reconstruction quality against the delivered bandwidth, the Pareto front, the bus's cap (vertical)
    and rings around the points where the bus limited the method's stream."""
    methods = row_methods(rows)
    stream_of = {m: METHODS[m].emulator for m in methods}
    points = [(_bandwidth(row, stream_of[m]), row[f"{m}_ssim"], m, bool(row.get(f"{stream_of[m]}_bus_limited")))
              for row in rows for m in methods
              if f"{stream_of[m]}_events_per_s" in row and np.isfinite(row[f"{m}_ssim"])]
    if not points:
        return None
    per_pixel = all(row.get("pixels") for row in rows)
    positive = [p[0] for p in points if p[0] > 0]
    floor = 10 ** np.floor(np.log10(min(positive) / 2)) if positive else 1.0
    fig, ax = plt.subplots(figsize=(8.5, 4.8), layout="constrained")
    for k, m in enumerate(methods):
        if any(p[2] == m for p in points):
            ax.plot([], [], linestyle="none", marker="o", markersize=5, color=f"C{k % 10}", label=method_label(m))
        for limited in (False, True):
            pts = np.array([(p[0], p[1]) for p in points if p[2] == m and p[3] == limited])
            if len(pts):
                style = BUS_LIMITED_MARKER if limited else {"marker": "o", "markersize": 5}
                ax.plot(np.maximum(pts[:, 0], floor), pts[:, 1], linestyle="none", color=f"C{k % 10}", **style)
    front = pareto_front([(p[0], p[1]) for p in points])
    ax.plot([max(p[0], floor) for p in front], [p[1] for p in front], "k--", lw=1, label="Pareto front")
    if per_pixel:
        draw_bus_cap(ax, rows, vertical=True)
    if any(p[3] for p in points):
        ax.plot([], [], color="0.3", linestyle="none", label=BUS_LIMITED_TEXT, **BUS_LIMITED_MARKER)
    ax.set_xscale("log")
    unit = "delivered ev/px/s" if per_pixel else "delivered events/s"
    zero = f" (0 drawn at {floor:g})" if any(p[0] <= 0 for p in points) else ""
    ax.set_xlabel(f"{unit} of the method's stream{zero}")
    ax.set_ylabel("SSIM vs flicker-free reference")
    ax.set_title(wrap("Reconstruction quality against the bandwidth the bus delivered", 80), fontsize=10)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0)
    ax.grid(alpha=0.3, which="both")
    from gevsim.plots import save_figure

    save_figure(fig, folder / "pareto.png")
    cap = [c for c in bus_caps(rows) if np.isfinite(c)]
    return ("pareto.png", "Reconstruction quality against the bandwidth the bus delivered; the dashed line is the "
                          "Pareto front (fewest events for a given SSIM)"
                          + (f"; dash-dot: the bus's cap ({number(max(cap))} ev/px/s)" if cap else "")
                          + "; rings: the bus limited the method's stream.")


def pareto_front(points: list[tuple[float, float]]) -> list[tuple[float, float]]:
    """Points not dominated by another with fewer-or-equal events and higher-or-equal quality."""
    front, best = [], -np.inf
    for cost, q in sorted(points, key=lambda p: (p[0], -p[1])):
        if q > best:
            front.append((cost, q))
            best = q
    return front


def _map_title(row: dict, e: str) -> str:
    """A flicker map's title: the stream's delivered rate, its rate at the pixels, and whether the bus limited it."""
    iv = interval_of(row, f"{e}_flicker_per_pixel_s")
    pixel = interval_of(row, f"{e}_pixel_flicker_per_pixel_s")
    text = f"{stream_label(e)}, delivered: {iv.format() if iv else ''}"
    if pixel:
        text += f"; at the pixels: {pixel.format()}"
    text += " (bus-limited)" if row.get(f"{e}_bus_limited") else ""
    return wrap(text, 44) + "\nflicker-induced delivered ev/px/s"


def flicker_maps(folder: Path, study: Study, row: dict, maps: dict, index: int, plt: Any) -> tuple[str, str]:
    """One run's panel: the scene's chip illuminance, the dominant light group, and each emulator's
    flicker-induced events per pixel delivered by the bus (mean over repeats; diverging colours, negative
    where flicker removed events)."""
    from matplotlib.colors import ListedColormap, SymLogNorm

    emulators = [e for e in EMULATORS if f"{e}_flicker_per_pixel_s" in maps]
    n = 2 + len(emulators)
    cols = min(n, 3)
    nrows = -(-n // cols)
    fig, grid = plt.subplots(nrows, cols, figsize=(3.9 * cols, 3.3 * nrows + 0.5), squeeze=False,
                             layout="constrained")
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
        ax.set_title(_map_title(row, e), fontsize=7)
        fig.colorbar(im, ax=ax, fraction=0.046)
    for ax in axes:
        ax.set_xticks([])
        ax.set_yticks([])
    fig.suptitle(wrap(", ".join(f"{a}={row.get(a)}" for a in study.axes)
                      + f" (flickering group: {row['flicker_group']})", 100), fontsize=9)
    from gevsim.plots import save_figure

    name = f"maps_{index:02d}.png"
    save_figure(fig, folder / name)
    caption = (f"Where flicker events come from ({', '.join(f'{a}={row.get(a)}' for a in study.axes)}): chip "
               "illuminance, dominant light group, and flicker-induced events per pixel per second each stream's "
               "bus delivered (mean of the repeats' run minus no-flicker; red: flicker adds events, blue: removes "
               "them; a bus-limited stream's map shows where the bus served requests, not all the flicker).")
    return name, caption
