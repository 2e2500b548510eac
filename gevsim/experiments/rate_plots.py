"""A study's flicker figures, pixels and bus apart: ``flicker_rate.png`` (flicker-induced events per
pixel per second of each stream) and ``headline.png`` (the DVS / gradient rejection ratio).

The primary series is what the pixels made (the readout's requests, ``<e>_pixel_flicker_per_pixel_s``);
what the bus delivered (``<e>_flicker_per_pixel_s``) is drawn lighter and dashed, a bus-limited stream's
delivered points circled, and the bus's cap as a line of its own: a full bus delivers its cap whatever
the flicker, so its figure is never drawn as a flicker measurement. Rows of studies made before the
pixel level was kept have only the delivered series, drawn as the primary one.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from gevsim.emulation.emulators import EMULATORS, HEADLINE
from gevsim.experiments.aggregate import row_emulators
from gevsim.experiments.plot_axes import (
    BUS_CAP_STYLE,
    BUS_LIMITED_MARKER,
    BUS_LIMITED_TEXT,
    axis_label,
    draw_bus_cap,
    errorbars,
    finish,
    log_x,
    mark_bus_limited,
    row_xy,
    series_labels,
    stream_label,
    wrap,
    x_axis,
)
from gevsim.experiments.study import Study

#: Delivered series: as light as this next to the pixels' own.
DELIVERED_ALPHA = 0.45
DELIVERED_STYLE: dict[str, Any] = {"linestyle": "--", "alpha": DELIVERED_ALPHA, "markersize": 4.0}


def _ratio_levels(rows: list[dict]) -> list[tuple[str, bool]]:
    """The ratio keys to draw, primary first: (key prefix, whether it is the delivered level)."""
    levels = [("pixel_", False)] if "pixel_flicker_rejection_ratio" in rows[0] else []
    return levels + ([("", True)] if "flicker_rejection_ratio" in rows[0] else [])


def _finite(rows: list[dict], prefix: str) -> bool:
    return any(np.isfinite(r.get(f"{prefix}flicker_rejection_ratio", math.nan)) for r in rows)


def _ratio_legend(fig: Any, groups: list[str], levels: list[tuple[str, bool]], rows: list[dict], bounds: bool) -> None:
    """Two legends under the axes: colour = series, line and marker = level."""
    from matplotlib.lines import Line2D

    series = [Line2D([], [], color=f"C{k % 10}", lw=2.5, label=g) for k, g in enumerate(groups)]
    base, cand = (stream_label(e) for e in HEADLINE)
    kinds = []
    for prefix, delivered in levels:
        if not delivered:
            kinds.append(Line2D([], [], color="0.3", marker="o", label="at the pixels (before the bus)"))
        elif _finite(rows, prefix):
            kinds.append(Line2D([], [], color="0.3", marker="o", label="delivered by the bus",
                                **(DELIVERED_STYLE if len(levels) > 1 else {})))
        else:
            kinds.append(Line2D([], [], linestyle="none", label=f"delivered by the bus: no ratio (the bus limits "
                                                               f"{base} or {cand} in every run)"))
    if bounds:
        kinds.append(Line2D([], [], color="0.3", marker="^", markerfacecolor="none", linestyle="none",
                            label=f"lower bound ({cand} rate not distinguishable from zero)"))
    kinds.append(Line2D([], [], color="0.4", lw=0.8, ls="--", label="1: no rejection"))
    fig.legend(handles=series, title="series", fontsize=7, title_fontsize=8, loc="outside lower left")
    fig.legend(handles=kinds, title="level", fontsize=7, title_fontsize=8, loc="outside lower right")


def headline(folder: Path, study: Study, rows: list[dict], plt: Any) -> tuple[str, str] | None:
    """The DVS / gradient flicker-rejection ratio with Fieller intervals against the swept axis: at the
    pixels (solid) and delivered by the bus (light, dashed; no ratio where the bus limits either stream)."""
    levels = _ratio_levels(rows)
    values = [r[f"{p}flicker_rejection_ratio{k}"] for r in rows for p, _ in levels for k in ("", "_low")
              if np.isfinite(r.get(f"{p}flicker_rejection_ratio{k}", math.nan))]
    if not values:  # no ratio at either level: nothing to draw
        return None
    x = x_axis(study)
    _, label = series_labels(study)
    groups = list(dict.fromkeys(label(r) for r in rows))
    fig, ax = plt.subplots(figsize=(9.0, 6.2), layout="constrained")
    spread = np.linspace(0.97, 1.03, len(groups)) if len(groups) > 1 and log_x(rows, x) else np.ones(len(groups))
    symlog = any(v <= 0 for v in values)  # flicker removed gradient events somewhere: show the sign
    numeric, xs, labels = True, list[Any](), list[str]()
    bounds = False
    for k, group in enumerate(groups):
        sel, xs, numeric, labels = row_xy([r for r in rows if label(r) == group], x)
        off = spread[k] if numeric else 1.0
        xs_plot = xs if numeric else [v + 0.06 * (k - (len(groups) - 1) / 2) for v in xs]
        for prefix, delivered in levels:
            style = DELIVERED_STYLE if delivered and len(levels) > 1 else {}
            errorbars(ax, xs_plot, sel, f"{prefix}flicker_rejection_ratio", offset=off, log=not symlog,
                      color=f"C{k % 10}", **style)
            at_least = [r.get(f"{prefix}flicker_rejection_ratio_at_least") for r in sel]
            pts = [(xv * off, b) for xv, b in zip(xs_plot, at_least) if b]
            if pts:
                ax.plot(*zip(*pts), "^", color=f"C{k % 10}", markersize=8, markerfacecolor="none",
                        alpha=style.get("alpha", 1.0))
                bounds = True
    ax.axhline(1.0, color="0.4", lw=0.8, ls="--")
    if symlog:
        ax.set_yscale("symlog", linthresh=0.1)
        ax.axhline(0.0, color="0.2", lw=0.6)
    else:
        ax.set_yscale("log")
    base, cand = (stream_label(e) for e in HEADLINE)
    where = ("at the pixels (dashed: delivered)" if len(levels) > 1 and _finite(rows, "") else
             "at the pixels" if not levels[0][1] else "delivered by the bus")
    ax.set_ylabel(wrap(f"{base} / {cand} flicker-induced events {where}", 45))
    finish(ax, axis_label(x), numeric, xs, labels, log_x(rows, x))
    ax.set_title(wrap(f"{study.name}: how many times fewer flicker-induced events {cand} events carry than {base} "
                      f"({rows[0]['repeats']} paired repeats, 95\u00a0% Fieller intervals; >\u00a01: {cand} "
                      f"rejects the flicker; <\u00a00: flicker removes {cand} events)", 80), fontsize=10)
    _ratio_legend(fig, groups, levels, rows, bounds)
    from gevsim.plots import save_figure

    save_figure(fig, folder / "headline.png")
    return ("headline.png", f"How many times fewer flicker-induced events {cand} events carry than {base} events "
                            f"(> 1: {cand} rejects the flicker), with 95 % intervals (Fieller, paired repeats): "
                            "solid, at the pixels (what they made, before the bus); light dashed, what the bus "
                            "delivered (no ratio where the bus limits either stream: a full bus delivers its cap "
                            "whatever the flicker); arrows: the interval is open-ended; triangles: a one-sided "
                            "lower bound where the gradient rate is not distinguishable from zero; grey dashed: "
                            "no rejection.")


def _rate_series(ax: Any, xs: list, sel: list[dict], e: str, shift: float) -> dict[str, bool]:
    """One stream's series in one panel; returns which kinds of marks it drew."""
    c = EMULATORS[e].color
    pixel = any(f"{e}_pixel_flicker_per_pixel_s" in r for r in sel)
    drawn = {"pixel": pixel, "delivered": True}
    if pixel:
        errorbars(ax, xs, sel, f"{e}_pixel_flicker_per_pixel_s", color=c, log=False, offset=shift)
    errorbars(ax, xs, sel, f"{e}_flicker_per_pixel_s", color=c, log=False, offset=shift,
              **(DELIVERED_STYLE if pixel else {}))
    drawn["bus_limited"] = mark_bus_limited(ax, np.asarray(xs, float) * shift, sel, e, f"{e}_flicker_per_pixel_s",
                                            color=c) > 0
    drawn["locked"] = any(f"{e}_phase_locked_per_pixel_s" in r for r in sel)
    if drawn["locked"]:
        errorbars(ax, xs, sel, f"{e}_phase_locked_per_pixel_s", color=c, marker="x", linestyle="none", log=False,
                  offset=shift * 1.01, alpha=DELIVERED_ALPHA, markersize=5.0)
    floor = [r.get(f"{e}_render_floor_per_pixel_s", math.nan) for r in sel]
    drawn["floor"] = bool(np.isfinite(floor).any())
    ax.plot(np.asarray(xs, float) * shift, floor, ":", color=c, alpha=0.8)
    return drawn


def _rate_legend(fig: Any, emulators: list[str], drawn: dict[str, bool], caps: list[Any]) -> None:
    """Two legends: colour = stream (a row under the panels), line and marker = level (beside them)."""
    from matplotlib.lines import Line2D

    streams = [Line2D([], [], color=EMULATORS[e].color, lw=2.5, label=stream_label(e)) for e in emulators]
    grey: dict[str, Any] = {"color": "0.3"}
    kinds = []
    if drawn.get("pixel"):
        kinds.append(Line2D([], [], marker="o", label="flicker-induced, at the pixels (before the bus)", **grey))
    kinds.append(Line2D([], [], marker="o", label="flicker-induced, delivered by the bus",
                        **grey, **(DELIVERED_STYLE if drawn.get("pixel") else {})))
    if drawn.get("bus_limited"):
        kinds.append(Line2D([], [], linestyle="none", label=BUS_LIMITED_TEXT, **grey,
                            **BUS_LIMITED_MARKER))
    if drawn.get("locked"):
        kinds.append(Line2D([], [], marker="x", linestyle="none", alpha=DELIVERED_ALPHA,
                            label="lamp-locked RMS, delivered", **grey))
    if drawn.get("floor"):
        kinds.append(Line2D([], [], linestyle=":", label="render-noise floor, delivered", **grey))
    kinds += [Line2D([], [], label=c.get_label(), **BUS_CAP_STYLE) for c in caps]
    fig.legend(handles=streams, fontsize=9, loc="outside lower center", ncol=len(streams), title="colour: stream",
               title_fontsize=8)
    fig.legend(handles=kinds, title="line and marker: level", fontsize=8, title_fontsize=8,
               loc="outside right upper")


def rates(folder: Path, study: Study, rows: list[dict], plt: Any) -> tuple[str, str]:
    """Flicker-induced events per emulator, one panel per series: at the pixels (solid), delivered by the
    bus (light, dashed; rings where the bus limited the stream), the bus's cap, the phase-locked
    RMS (x) and the render-noise floor (dotted), with 95 % intervals."""
    x = x_axis(study)
    _, label = series_labels(study)
    groups = list(dict.fromkeys(label(r) for r in rows))
    emulators = row_emulators(rows)
    cols = 2 if len(groups) == 4 else min(3, len(groups))
    nrows = -(-len(groups) // cols)
    fig, axes = plt.subplots(nrows, cols, figsize=(4.6 * cols + 3.6, 3.7 * nrows + 1.0), squeeze=False,
                             sharey=True, layout="constrained")
    for ax in axes.ravel()[len(groups):]:
        ax.axis("off")
    use_log = log_x(rows, x)
    drawn: dict[str, bool] = {}
    caps: dict[str, Any] = {}
    for ax, group in zip(axes.ravel(), groups):
        sel, xs, numeric, labels = row_xy([r for r in rows if label(r) == group], x)
        for k, e in enumerate(emulators):
            shift = (1.0 + 0.02 * (k - len(emulators) / 2)) if numeric and use_log else 1.0
            for kind, yes in _rate_series(ax, xs, sel, e, shift).items():
                drawn[kind] = drawn.get(kind, False) or yes
        if draw_bus_cap(ax, sel, xs=xs):
            caps.update({line.get_label(): line for line in ax.lines if line.get_label().startswith("bus cap")})
        ax.set_yscale("symlog", linthresh=1.0)
        finish(ax, axis_label(x), numeric, xs, labels, use_log)
        ax.set_title(wrap(group, 50), fontsize=9)
    level = "at the pixels (solid),\ndelivered (dashed)" if drawn.get("pixel") else "delivered by the bus"
    for ax in axes[:, 0]:
        ax.set_ylabel(f"flicker-induced ev/px/s\n{level}")
    _rate_legend(fig, emulators, drawn, list(caps.values()))
    fig.suptitle(wrap(f"Flicker-induced events per pixel per second: what the pixels made and what the bus "
                      f"delivered (mean of {rows[0]['repeats']} repeats, 95 % intervals; symmetric log axis: "
                      "negative estimates drawn where they are)", 75), fontsize=10)
    from gevsim.plots import save_figure

    save_figure(fig, folder / "flicker_rate.png")
    return ("flicker_rate.png", "Flicker-induced events per pixel per second, mean over repeats with 95 % t "
                                "intervals (run minus its flicker-free counterfactual): solid, what the pixels "
                                "made (the readout's requests, before the bus); light dashed, what the bus "
                                "delivered; rings: the bus limited that stream (its delivered figure "
                                "measures the bus, not the flicker); dash-dot line: the bus's cap; x: RMS of the "
                                "delivered rate modulation locked to the lamp phase (bootstrap interval, no "
                                "subtraction); dotted: the render-noise floor of the delivered stream.")
