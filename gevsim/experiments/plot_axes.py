"""What every study figure shares: the swept axis in physical units, points with their 95 % intervals,
human stream names, and the readout bus drawn as what it is.

A stream's counts are measured at two levels: what its pixels made (the readout's requests, before
the bus) and what the bus delivered. Where the readout lost more than 1 % of the requests
(``<e>_bus_limited``) the delivered figure measures the bus, not the scene: such points are drawn
circled (:func:`mark_bus_limited`) and the bus's cap (``bus_cap_per_pixel_s``, ev/px/s) is a line of its
own (:func:`draw_bus_cap`), so a saturated figure is never read as a flicker measurement.
"""

from __future__ import annotations

import math
import textwrap
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from gevsim.emulation.emulators import EMULATORS
from gevsim.evaluation.methods import METHODS
from gevsim.experiments.aggregate import interval_of
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
    "window": ("emulated pixels (window of the chip)", "pixels"),
}

#: How a bus-limited point is drawn: a hollow ring around the point, larger than any series' own marker.
BUS_LIMITED_MARKER: dict[str, Any] = {"marker": "o", "markersize": 13, "markerfacecolor": "none",
                                      "markeredgewidth": 1.5}
#: How the bus's cap is drawn: a dark dash-dot line.
BUS_CAP_STYLE: dict[str, Any] = {"color": "0.1", "linestyle": (0, (7, 2, 1.5, 2)), "linewidth": 1.3}
#: Legend text of a bus-limited point.
BUS_LIMITED_TEXT = "bus-limited (its readout lost > 1 % of the requests)"


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


def stream_label(emulator: str) -> str:
    """A stream's human name (DVS, gradient, gradient RC, CSDVS); an unknown name as it is."""
    return EMULATORS[emulator].label if emulator in EMULATORS else emulator


def method_label(method: str) -> str:
    """A reconstruction method with the stream it reads, e.g. ``dct_rc (gradient RC)``."""
    return f"{method} ({stream_label(METHODS[method].emulator)})" if method in METHODS else method


def wrap(text: str, width: int = 90) -> str:
    """``text`` wrapped to lines of at most ``width`` characters (its own line breaks kept), for a title."""
    return "\n".join(textwrap.fill(part, width, break_on_hyphens=False) for part in text.split("\n"))


def number(value: float) -> str:
    """A rate as a person reads it: 133, 1,980, 4.2, 0.0123."""
    return f"{value:,.0f}" if abs(value) >= 100 else f"{value:.3g}"


def row_xy(rows: list[dict], x: str) -> tuple[list[dict], list[Any], bool, list[str]]:
    """The rows in x order, their x values (positions 0, 1, ... where x is not numeric), whether x is
    numeric, and the x values as text."""
    vals = [x_value(r, x) for r in rows]
    numeric = all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in vals)
    order = sorted(range(len(rows)), key=lambda i: vals[i] if numeric else str(vals[i]))
    return [rows[i] for i in order], ([vals[i] for i in order] if numeric else list(range(len(order)))), \
        numeric, [str(vals[i]) for i in order]


def errorbars(ax: Any, xs: Sequence[float], rows: list[dict], key: str, *, color: str | None = None,
              marker: str = "o", label: str | None = None, offset: float = 1.0, linestyle: Any = "-",
              log: bool = True, fill: str = "full", alpha: float = 1.0, markersize: float = 6.0) -> Any:
    """Points with their interval (``key``, ``key_low``, ``key_high``); on a log axis, an interval end
    at or below zero or infinite is drawn to the edge with an arrow."""
    ivs = [interval_of(r, key) for r in rows]
    est = np.array([iv.estimate if iv else r.get(key, math.nan) for iv, r in zip(ivs, rows)], float)
    lo = np.array([iv.low if iv else math.nan for iv in ivs], float)
    hi = np.array([iv.high if iv else math.nan for iv in ivs], float)
    x = np.asarray(xs, float) * offset
    face = color if fill == "full" else "none"
    line = ax.plot(x, np.where(np.isfinite(est) & ((est > 0) | (not log)), est, np.nan), marker=marker,
                   linestyle=linestyle, color=color, label=label, markerfacecolor=face, alpha=alpha,
                   markersize=markersize)[0]
    color = line.get_color()
    for xi, e, a, b in zip(x, est, lo, hi):
        if not (np.isfinite(a) or np.isfinite(b)) and not np.isfinite(e):
            continue
        a_ok = np.isfinite(a) and (a > 0 or not log)
        b_ok = np.isfinite(b)
        ya = a if a_ok else None
        yb = b if b_ok else None
        if ya is not None and yb is not None:
            ax.plot([xi, xi], [ya, yb], color=color, lw=1.2, alpha=0.8 * alpha)
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


def finish(ax: Any, xlabel: str, numeric: bool, xs: Sequence[Any], labels: list[str], log_x: bool) -> None:
    """The x axis (log where the values span a decade, the values' text where they are not numbers), a
    grid, and the intervals' open ends."""
    if numeric and log_x:
        from matplotlib.ticker import NullFormatter

        ax.set_xscale("log")
        ax.xaxis.set_minor_formatter(NullFormatter())
    if not numeric:
        ax.set_xticks(xs, labels, rotation=20)
    ax.set_xlabel(xlabel)
    ax.grid(alpha=0.3, which="both")
    open_ends(ax)


def log_x(rows: list[dict], x: str) -> bool:
    """Whether the x values are positive numbers spanning at least a decade (drawn on a log axis)."""
    vals = [x_value(r, x) for r in rows]
    vals = [v for v in vals if isinstance(v, (int, float)) and not isinstance(v, bool)]
    return bool(vals) and min(vals) > 0 and max(vals) / min(vals) >= 10


def bus_caps(rows: list[dict]) -> list[float]:
    """The bus's cap (ev/px/s) of each row, NaN where the bus is unlimited or the row does not say."""
    caps = [row.get("bus_cap_per_pixel_s") for row in rows]
    return [float(c) if isinstance(c, (int, float)) and c > 0 and math.isfinite(c) else math.nan for c in caps]


def draw_bus_cap(ax: Any, rows: list[dict], *, xs: Sequence[float] | None = None, vertical: bool = False) -> bool:
    """The bus's cap as a line labelled ``bus cap N ev/px/s``: horizontal (a rate axis) or ``vertical`` (a
    bandwidth axis); where the cap differs between rows, a line through each row's cap at ``xs``.
    Returns whether a cap was drawn."""
    caps = bus_caps(rows)
    known = sorted({c for c in caps if math.isfinite(c)})
    if not known:
        return False
    if len(known) == 1 or xs is None:
        for cap in known:
            line = ax.axvline if vertical else ax.axhline
            line(cap, label=f"bus cap {number(cap)} ev/px/s", zorder=1.5, **BUS_CAP_STYLE)
    else:
        ax.plot(np.asarray(xs, float), caps, label=f"bus cap {number(known[0])}-{number(known[-1])} ev/px/s",
                zorder=1.5, **BUS_CAP_STYLE)
    return True


def mark_bus_limited(ax: Any, xs: Sequence[float] | np.ndarray, rows: list[dict], emulator: str, key: str, *,
                     color: str) -> int:
    """A hollow ring around each point of ``key`` where ``emulator``'s stream was bus-limited; returns how many."""
    pts = [(x, r.get(key, math.nan)) for x, r in zip(np.asarray(xs, float), rows) if r.get(f"{emulator}_bus_limited")]
    pts = [(x, y) for x, y in pts if isinstance(y, (int, float)) and math.isfinite(y)]
    if pts:
        ax.plot(*zip(*pts), linestyle="none", color=color, zorder=4, **BUS_LIMITED_MARKER)
    return len(pts)
