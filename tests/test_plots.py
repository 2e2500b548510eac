"""Plots draw the model's own waveforms: a PWM's edges are vertical steps, not slopes between samples."""

from __future__ import annotations

import numpy as np

from gevsim.illumination import from_spec
from gevsim.plots import waveform_samples


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

    from gevsim.plots import _lux_scale, contact_sheet
    from gevsim.tonemap import ToneMap

    frames = np.exp(np.linspace(-6, 0, 4 * 6 * 8)).reshape(4, 6, 8, 1)  # W/m^2, photopic-equivalent
    contact_sheet(frames, [0.0, 1e-3, 2e-3, 3e-3], tmp_path / "sheet.png", title="t")
    assert (tmp_path / "sheet.png").stat().st_size > 0
    tone = ToneMap(low=-6.0, high=0.0)
    fig = plt.figure()
    _lux_scale(fig, tone)
    labels = [t.get_text() for t in fig.axes[-1].get_yticklabels()]
    assert labels[0] == f"{683.0 * np.exp(-6.0):.3g}" and labels[-1] == "683"  # grey 0 and 1 in lux
    plt.close(fig)


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
