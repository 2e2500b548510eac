"""Plots draw the model's own waveforms: a PWM's edges are vertical steps, not slopes between samples."""

from __future__ import annotations

import numpy as np
import pytest

from gevsim.illumination import from_spec
from gevsim.plots import SHEET_DECADES, UNDER_RGB, _lux_scale, contact_sheet, sheet_scale, waveform_samples
from gevsim.tonemap import ToneMap


def test_a_pwm_is_drawn_with_its_edges_and_only_its_two_levels():
    wf = from_spec({"type": "pwm", "frequency_hz": 500.0, "duty": 0.3})
    t, w = waveform_samples(wf, 0.01)
    levels = np.unique(np.round(w, 9))
    assert len(levels) == 2  # every drawn point is on or off: no point half way up an edge
    edges = wf.breakpoints_s(0.0, 0.01)
    assert len(edges) == 9  # 5 periods: on at 0 (the start), off at 0.6 ms, on at 2 ms, ...
    for e in edges[(edges > 0) & (edges < 0.01)]:
        before, after = w[np.searchsorted(t, e) - 1], w[np.searchsorted(t, e, side="right")]
        assert abs(t[np.searchsorted(t, e) - 1] - e) < 1e-9 and before != after  # a vertical step at e


def test_the_contact_sheet_has_a_scale_in_lux(tmp_path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    frames = np.exp(np.linspace(-6, 0, 4 * 6 * 8)).reshape(4, 6, 8, 1)  # W/m^2, photopic-equivalent
    contact_sheet(frames, [0.0, 1e-3, 2e-3, 3e-3], tmp_path / "sheet.png", title="t")
    assert (tmp_path / "sheet.png").stat().st_size > 0
    tone = ToneMap(low=-6.0, high=0.0)
    fig = plt.figure()
    bar = _lux_scale(fig, tone)
    labels = [t.get_text() for t in fig.axes[-1].get_yticklabels()]
    assert labels[0] == f"{683.0 * np.exp(-6.0):.3g}" and labels[-1] == "683"  # grey 0 and 1 in lux
    assert bar.extend == "min" and np.allclose(bar.cmap.get_under()[:3], UNDER_RGB)  # darker: drawn as such
    plt.close(fig)


def _mostly_black(black: float) -> np.ndarray:
    """Four 40 x 50 frames, 90 % of each ``black``, the rest a lit scene of 0.01 to 10 W/m^2."""
    rng = np.random.default_rng(7)
    frames = np.full((4, 40, 50, 1), black)
    frames[:, :4, :] = 10 ** rng.uniform(-2, 1, size=(4, 4, 50, 1))
    return frames


@pytest.mark.parametrize("black", [0.0, 1e-12])
def test_the_contact_sheet_scale_comes_from_the_lit_pixels_when_90_percent_is_black(black):
    frames = _mostly_black(black)
    lit = frames[:, :4].ravel()
    tone = sheet_scale(frames)
    assert np.exp(tone.high) == pytest.approx(np.percentile(lit, 99.5))
    assert np.exp(tone.low) == pytest.approx(np.percentile(lit, 0.5))  # the lit scene's own 3 decades
    assert ToneMap.from_ground_truth(np.log(np.maximum(frames, 1e-12))).low < np.log(1e-11)  # the old scale


def test_the_contact_sheet_shows_at_most_4_5_decades_and_draws_darker_pixels_as_clipped(tmp_path, monkeypatch):
    import matplotlib.pyplot as plt

    import gevsim.plots as plots

    frames = _mostly_black(0.0)
    frames[:, :2] = 10 ** np.linspace(-7, 1, 2 * 50).reshape(1, 2, 50, 1)  # a lit scene spanning 8 decades
    tone = sheet_scale(frames)
    assert tone.high - tone.low == pytest.approx(SHEET_DECADES * np.log(10.0))
    kept = []
    monkeypatch.setattr(plots, "save_figure", lambda fig, path: kept.append(fig))
    contact_sheet(frames, [0.0, 1e-3, 2e-3, 3e-3], tmp_path / "sheet.png", title="t")
    shown = kept[0].axes[0].get_images()[0].get_array()
    dark = frames[0, ..., 0] < np.exp(tone.low)
    assert dark.mean() > 0.9 and np.allclose(shown[dark], UNDER_RGB)  # background and the darkest: clipped
    assert not np.allclose(shown[~dark], UNDER_RGB, atol=0.02)
    plt.close(kept[0])


def test_quality_plot_gives_each_method_one_colour_and_each_series_one_line_style():
    """Issue 26 item 8: 16 curves (4 methods x 4 series) once cycled through 10 colours, so two methods
    shared a colour; now the colour names the method in every series and the line style the series."""
    from gevsim.experiments.study_plots import method_styles

    methods = ["dct", "dct_rc", "direct", "complementary"]
    groups = [f"scene={s}, hysteresis_ln={h}" for s in ("office", "street") for h in (0.0, 0.02)]
    colours, styles = method_styles(methods, groups)
    assert len(set(colours.values())) == len(methods)
    assert len(set(styles.values())) == len(groups)
    many = [f"g{k}" for k in range(12)]
    assert len(set(method_styles(methods, many)[1].values())) == 12
