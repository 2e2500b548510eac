"""`gevsim validate`: the presets against published measurements (the bands of issue 23), labelled fit, held
out, self or definition (issue 34), against their own statement of what the pixel does, and against themselves."""

import dataclasses
import json

import numpy as np
import pytest

from gevsim.pixel import load_preset
from gevsim.validation.checks import (
    LABELS,
    STATED_TOLERANCE,
    Settings,
    agree,
    check_background,
    check_bandwidth,
    check_mismatch,
    check_readout,
    check_stated,
    published,
    scene_to_chip_lux,
    within_2x,
)
from gevsim.validation.measure import Rate, intrinsic_correlation, intrinsic_spread, rate_interval

#: The keys that state a held-out row's band, by table.
BANDS = {"background_activity": "band", "off_share": "at_most", "pixel_spread": "band", "on_off_correlation": "within",
         "bandwidth": "tolerance", "latency": "band_s", "threshold_mismatch": "band"}


def test_rate_interval_rules():
    r = rate_interval(np.zeros(100), 10.0)
    assert (r.value, r.low) == (0.0, 0.0) and r.high == pytest.approx(3.0 / 1000)
    r = rate_interval(np.full(100, 5), 1.0)  # identical pixels: the Poisson interval of 500 events
    assert r.value == 5.0 and r.low == pytest.approx(5 - 1.96 * np.sqrt(500) / 100, rel=1e-3)
    assert within_2x(Rate(0.0, 0.0, 0.003), 0.001) and not within_2x(Rate(1.0, 0.9, 1.1), 0.3)
    assert agree(Rate(1.0, 0.9, 1.1), Rate(1.05, 1.0, 1.1)) and not agree(Rate(1.0, 0.99, 1.01), Rate(2, 1.9, 2.1))


def test_scene_to_chip_lux_is_l08s_reference():
    assert scene_to_chip_lux(1000.0, reflectance=0.5, f_number=1.4, transmission=0.9) == pytest.approx(57.4, rel=1e-3)


def test_every_published_entry_is_labelled_and_its_source_named_in_full():
    """Issue 34: each entry says whether a parameter was set from it (fit: which one), whether it is held out
    (with the band it is held to) or copied (definition), and names a source with its citation, what was taken
    from it and how its lux were read."""
    data = published()
    sources = data["sources"]
    for key, src in sources.items():
        assert {"cite", "data", "lux"} <= set(src), key
    for table, entries in data.items():
        if table == "sources":
            continue
        for e in entries:
            assert e["label"] in LABELS and e["label"] != "self", (table, e)
            assert e["source"] in sources and e.get("where"), (table, e)
            if e["label"] in ("fit", "definition"):
                assert e.get("sets"), (table, e)
            if e["label"] == "held out":
                assert BANDS[table] in e, (table, e)


@pytest.mark.parametrize("name", ["davis346", "dvs128"])
def test_each_dvs_preset_has_at_least_four_held_out_published_rows(name):
    held = [e for table, entries in published().items() if table != "sources" for e in entries
            if name in e["sensors"] and e["label"] == "held out"]
    assert len(held) >= 4, held


@pytest.mark.parametrize("name", ["davis346", "dvs128"])
def test_background_activity_fits_hold_and_the_held_out_rows_are_judged(name):
    """Issue 23's bar, kept for the fitted points: DVS background activity within 2x of IEBCS's measured
    DAVIS rates (0.1 lux ON and OFF, 161 and 3000 lux ON). The held-out rows (DND21's dark, the OFF share when
    bright, the pixel-to-pixel spread and ON/OFF correlation at 0.1 lux) each get a verdict; those that fail
    say why."""
    rows = check_background(load_preset(name), Settings(shape=(16, 16), duration_s=3.0), published())
    assert len(rows) == 10 and {r.label for r in rows} == {"fit", "held out"}
    fits = [r for r in rows if r.label == "fit"]
    assert len(fits) == 4 and all(r.verdict == "pass" for r in fits), fits
    assert all(r.verdict in ("pass", "fail") for r in rows)
    assert all(r.caveat for r in rows if r.verdict == "fail")


def test_intrinsic_spread_and_correlation_take_out_the_poisson_scatter():
    rng = np.random.default_rng(0)
    same = rng.poisson(30.0, 20000)
    assert intrinsic_spread(same) < 0.02
    rates = 30.0 * rng.gamma(1 / 0.6**2, 0.6**2, 20000)  # CV 0.6 from pixel to pixel
    on, off = rng.poisson(rates), rng.poisson(0.8 * rates)  # both polarities follow the pixel's rate
    assert intrinsic_spread(on) == pytest.approx(0.6, abs=0.02)
    assert intrinsic_correlation(on, off) == pytest.approx(1.0, abs=0.03)
    assert abs(intrinsic_correlation(on, rng.poisson(rng.permutation(rates)))) < 0.05


def test_background_activity_falls_from_the_dark_to_bright_light():
    """Measured sensors (the sensor-physics audit's test V2): ~5 ev/px/s per polarity at 0.1 lux, ON/OFF
    symmetric there; at least 10x less at 100 lux, OFF gone and ON (leak) in [0.05, 0.3] when bright; and
    no rise with light from 0.01 to 100 lux (beyond the counting interval)."""
    from gevsim.validation.measure import background_activity

    p = load_preset("davis346")
    rates = {lux: background_activity(p, lux, shape=(16, 16), duration_s=3.0) for lux in (0.01, 0.1, 1.0, 10.0, 100.0)}
    dark_on, dark_off = rates[0.1]
    bright_on, bright_off = rates[100.0]
    assert 1.0 <= dark_on.value + dark_off.value <= 20.0 and 0.5 < dark_off.value / dark_on.value < 2.0
    assert dark_on.value + dark_off.value >= 10 * (bright_on.value + bright_off.value)
    assert bright_off.value <= 0.2 * bright_on.value and 0.05 <= bright_on.value <= 0.3
    totals = [(on.low + off.low, on.high + off.high) for on, off in rates.values()]
    for dim, bright in zip(totals[:-1], totals[1:]):
        assert bright[0] <= dim[1]  # not significantly more events in more light


def test_dvs128_bandwidth_latency_and_mismatch_match_l08():
    p = load_preset("dvs128")
    rows = check_bandwidth(p, Settings.quick(), published()) + check_mismatch(p, Settings.quick(), published())
    assert [r.verdict for r in rows] == ["pass", "pass", "pass"], rows
    assert [r.label for r in rows] == ["fit", "fit", "definition"]


@pytest.mark.parametrize("name", ["davis346", "dvs128"])
def test_the_stated_behaviour_is_measured_and_a_wrong_statement_fails(name):
    """Issue 34: validate measures the preset's [stated] bandwidth and latency at their own conditions (and the
    14 +- 2 events per cycle of a 0.5 ln sinusoid at that bandwidth) and fails a row when statement and
    behaviour differ by more than 10 %."""
    p = load_preset(name)
    rows = check_stated(p, Settings.quick(), published())
    assert len(rows) == 3 and all(r.label == "self" and r.verdict == "pass" for r in rows), rows
    for factor, verdict in ((1.0 + 0.5 * STATED_TOLERANCE, "pass"), (1.0 + 1.5 * STATED_TOLERANCE, "fail"),
                            (1.0 - 1.5 * STATED_TOLERANCE, "fail")):
        stated = dataclasses.replace(p.stated, bandwidth_hz=factor * p.stated.bandwidth_hz,
                                     latency_s=factor * p.stated.latency_s)
        moved = check_stated(dataclasses.replace(p, stated=stated), Settings.quick(), published())
        assert [moved[0].verdict, moved[2].verdict] == [verdict, verdict], (factor, moved)


def test_davis346_readout_cap():
    rows = check_readout(load_preset("davis346"), Settings.quick(), published())
    assert [(r.verdict, r.label) for r in rows] == [("pass", "definition")]


def test_davis346_held_out_sister_chip_rows():
    """B14's DAVIS240 (the DAVIS346's pixel): its 3.5 % matching holds the preset's assumed 3 % within 1.5x; its
    3 us minimum latency is far below the preset's 60.5 us, and the row fails saying why."""
    p = load_preset("davis346")
    mismatch = check_mismatch(p, Settings.quick(), published())
    latency = [r for r in check_bandwidth(p, Settings.quick(), published()) if r.source.startswith("B14")]
    assert [(r.label, r.verdict) for r in mismatch] == [("held out", "pass")]
    assert [(r.label, r.verdict) for r in latency] == [("held out", "fail")] and "latency_s" in latency[0].caveat


def test_cli_writes_the_report(tmp_path, capsys, monkeypatch):
    from gevsim import cli
    from gevsim.validation import report

    # The model's curves are plotted, not judged: three of their eleven illuminances keep the CLI test short
    # (11 s of the suite's 26 s); the rows are the full --quick set.
    monkeypatch.setattr(report, "CURVE_LUX", (0.1, 10.0, 3000.0))
    out = tmp_path / "val"
    code = cli.main(["validate", "--sensor", "dvs128", "--quick", "-q", "--out", str(out)])
    assert (out / "report.md").is_file() and (out / "dvs128" / "ba_vs_lux.png").is_file()
    res = json.loads((out / "dvs128" / "results.json").read_text())
    rows = res["rows"]
    assert {r["label"] for r in rows} == set(LABELS)
    failed = [r for r in rows if r["verdict"] == "fail"]
    assert code == (1 if failed else 0)
    assert all(r["label"] == "held out" and r["caveat"] for r in failed), failed  # every fit, self, definition passes
    assert sum(r["label"] == "held out" for r in rows) >= 4
    text = (out / "dvs128" / "report.md").read_text()
    assert "| check | label | source |" in text and "Lichtsteiner, C. Posch, T. Delbruck" in text
    assert len(res["curves"]["on_hz"]) == len(res["curves"]["chip_lux"])
    assert cli.main(["validate", "--sensor", "nosuch", "--out", str(out)]) != 0
    assert "nosuch" in capsys.readouterr().err
    assert (out / "report.md").is_file()  # the earlier report is kept


def test_measured_cutoff_is_the_photoreceptor_pole():
    """The bench's -3 dB (a 1 % sinusoid) equals cutoff_at(I + I_dark) within 3 % (the audit's test V3b), down
    to light below the dark current, when no output pole adds its own."""
    from gevsim.pixel.presets import with_overrides
    from gevsim.validation.measure import cutoff_hz, photocurrent_a

    p = with_overrides(load_preset("davis346"), {"second_pole_hz": None})
    for lux in (0.03, 1.0, 10.0):
        expected = float(p.photoreceptor.cutoff_at(photocurrent_a(p, lux) + p.noise.dark_current_a))
        assert cutoff_hz(p, lux, tolerance=0.002) == pytest.approx(expected, rel=0.03), lux
