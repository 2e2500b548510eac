"""Study figures keep the pixels and the bus apart (issue 35, item 5): the flicker rates at the pixels are
the primary series, what the bus delivered is drawn lighter, a bus-limited point is ringed and the bus's
cap is a line of its own; every label fits in its figure and names streams as people do."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

matplotlib = pytest.importorskip("matplotlib")
matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

import gevsim.plots  # noqa: E402
from gevsim.experiments import study_plots  # noqa: E402
from gevsim.experiments.plot_axes import BUS_LIMITED_MARKER  # noqa: E402

CAP = 133.0
EMULATORS = ("dvs", "gradient", "gradient_rc", "csdvs")


def _put(row, key, value, half=1.0):
    row[key], row[f"{key}_low"], row[f"{key}_high"] = value, value - half, value + half


def _row(lux, *, pixel=True, cap=CAP, limited=("dvs", "gradient")):
    """A demo-like row: DVS and gradient at the bus's cap, their pixels making far more."""
    row = {"scene": "office", "light_scale": lux, "chip_lux_median": 4.0 * lux, "repeats": 4, "pixels": 6912}
    made = {"dvs": 1980.0, "gradient": 62.9, "gradient_rc": 30.0, "csdvs": 1130.0}
    delivered = {"dvs": CAP, "gradient": 0.0, "gradient_rc": 32.0, "csdvs": 128.0}
    for e in EMULATORS:
        _put(row, f"{e}_flicker_per_pixel_s", delivered[e])
        if pixel:
            _put(row, f"{e}_pixel_flicker_per_pixel_s", made[e])
        row[f"{e}_bus_limited"] = e in limited
        row[f"{e}_events_per_s"] = (CAP if e in limited else 50.0) * row["pixels"]
    if cap is not None:
        row["bus_cap_per_pixel_s"] = cap
    for m in ("dct", "dct_rc", "direct"):
        _put(row, f"{m}_ssim", 0.6, 0.02)
    _put(row, "flicker_rejection_ratio", np.nan)
    _put(row, "pixel_flicker_rejection_ratio", 31.4, 5.0)
    return row


STUDY = SimpleNamespace(name="demo", report={"x": "light_scale"},
                        axes={"scene": ["office"], "light_scale": [1.0, 30.0]})


@pytest.fixture
def figures(monkeypatch):
    """The figures the plots save, kept open to inspect instead of written."""
    kept = []
    monkeypatch.setattr(gevsim.plots, "save_figure", lambda fig, path: kept.append(fig))
    yield kept
    for fig in kept:
        plt.close(fig)


def _words(text):
    return " ".join(text.split())


def _labelled(ax, start):
    return [line for line in ax.lines if str(line.get_label()).startswith(start)]


def _texts_inside(fig):
    """Every title, axis label and legend text of a figure lies inside it (nothing cut at the edges)."""
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    legends = list(fig.legends) + [ax.get_legend() for ax in fig.axes if ax.get_legend()]
    texts = [fig._suptitle] + [t for ax in fig.axes if ax.axison for t in (ax.title, ax.xaxis.label, ax.yaxis.label)]
    texts += [t for legend in legends for t in (*legend.get_texts(), legend.get_title())]
    texts = [t for t in texts if t is not None and t.get_visible() and t.get_text().strip()]
    assert len(texts) > 5
    for text in texts:
        box = text.get_window_extent(renderer)
        assert box.x0 >= -1 and box.y0 >= -1 and box.x1 <= fig.bbox.width + 1 and box.y1 <= fig.bbox.height + 1, \
            text.get_text()


def test_flicker_rates_draw_the_pixels_first_the_bus_lighter_and_its_cap_as_a_line(tmp_path, figures):
    rows = [_row(1.0), _row(30.0)]
    name, caption = study_plots.rates(tmp_path, STUDY, rows, plt)
    assert name == "flicker_rate.png" and "what the pixels made" in caption
    fig = figures[0]
    ax = fig.axes[0]
    caps = _labelled(ax, "bus cap")
    assert len(caps) == 1 and caps[0].get_label() == "bus cap 133 ev/px/s"
    assert np.allclose(caps[0].get_ydata(), CAP)  # a horizontal line at the cap's value
    dvs = [line for line in ax.lines if line.get_color() == "tab:red" and len(line.get_xdata()) == 2
           and line.get_marker() == "o" and line.get_markerfacecolor() != "none"]
    primary = [line for line in dvs if line.get_alpha() in (None, 1.0)]
    delivered = [line for line in dvs if line.get_linestyle() == "--"]
    assert np.allclose(primary[0].get_ydata(), 1980.0)  # the solid series: what the pixels made
    assert np.allclose(delivered[0].get_ydata(), CAP) and delivered[0].get_alpha() < 1  # the bus: lighter
    rings = [line for line in ax.lines if line.get_markersize() == BUS_LIMITED_MARKER["markersize"]
             and line.get_markerfacecolor() == "none"]
    ringed = sorted((line.get_color(), float(y)) for line in rings for y in line.get_ydata())
    assert ringed == [("tab:blue", 0.0)] * 2 + [("tab:red", CAP)] * 2  # DVS and gradient, each run
    assert "ev/px/s at the pixels (solid), delivered (dashed)" in _words(ax.get_ylabel())
    legend_text = [t.get_text() for legend in fig.legends for t in legend.get_texts()]
    assert "gradient RC" in legend_text and not any("gradient_rc" in t for t in legend_text)
    assert "bus cap 133 ev/px/s" in legend_text
    _texts_inside(fig)


def test_older_rows_without_the_pixel_level_or_a_cap_still_draw(tmp_path, figures):
    rows = [_row(1.0, pixel=False, cap=None, limited=()), _row(30.0, pixel=False, cap=None, limited=())]
    for r in rows:
        del r["pixel_flicker_rejection_ratio"]
        _put(r, "flicker_rejection_ratio", 20.0, 3.0)
    study_plots.rates(tmp_path, STUDY, rows, plt)
    assert study_plots.headline(tmp_path, STUDY, rows, plt)[0] == "headline.png"
    ax = figures[0].axes[0]
    assert not _labelled(ax, "bus cap") and "ev/px/s delivered by the bus" in _words(ax.get_ylabel())
    solid = [line for line in ax.lines if line.get_color() == "tab:red" and line.get_linestyle() == "-"
             and line.get_marker() == "o"]
    assert np.allclose(solid[0].get_ydata(), CAP)  # the delivered series is the primary one here


def test_the_headline_ratio_is_drawn_at_the_pixels_where_the_bus_has_none(tmp_path, figures):
    rows = [_row(1.0), _row(30.0)]
    assert study_plots.headline(tmp_path, STUDY, rows, plt)[0] == "headline.png"
    ax = figures[0].axes[0]
    drawn = [line for line in ax.lines if line.get_marker() == "o" and np.isfinite(line.get_ydata()).any()]
    assert len(drawn) == 1 and np.allclose(drawn[0].get_ydata(), 31.4)
    assert "events at the pixels" in _words(ax.get_ylabel())
    legend_text = [t.get_text() for legend in figures[0].legends for t in legend.get_texts()]
    assert any(t.startswith("delivered by the bus: no ratio") for t in legend_text)
    _texts_inside(figures[0])


def test_pareto_marks_the_bus_cap_and_bus_limited_points_on_a_delivered_axis(tmp_path, figures):
    rows = [_row(1.0), _row(30.0)]
    name, caption = study_plots.pareto(tmp_path, rows, plt)
    assert name == "pareto.png" and "cap (133 ev/px/s)" in caption
    ax = figures[0].axes[0]
    caps = _labelled(ax, "bus cap")
    assert len(caps) == 1 and np.allclose(caps[0].get_xdata(), CAP)  # vertical, at the cap
    assert ax.get_xlabel().startswith("delivered ev/px/s")
    rings = [line for line in ax.lines if line.get_markersize() == BUS_LIMITED_MARKER["markersize"]
             and line.get_markerfacecolor() == "none" and len(line.get_xdata())]
    xs = sorted(float(x) for line in rings for x in line.get_xdata())
    assert xs == [CAP] * 4  # dct (gradient) and direct (DVS) in both runs; dct_rc's stream is not limited
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert "dct_rc (gradient RC)" in labels and "direct (DVS)" in labels
    _texts_inside(figures[0])
