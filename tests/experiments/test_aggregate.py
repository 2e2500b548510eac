"""A study's aggregation on synthetic event streams with known truth: both flicker estimators
cover their true value, the paired design's intervals shrink with repeats and beat unpaired runs."""

import math

import numpy as np
import pytest

from gevsim.experiments.aggregate import aggregate_run, map_regions, region_shares
from gevsim.metrics.attribution import phase_histogram

PERIOD_S, DURATION_S, SHAPE = 0.002, 0.02, (8, 10)
PIXELS = SHAPE[0] * SHAPE[1]
FLICKER, BACKGROUND = 40.0, 300.0  # ev/px/s: flicker-induced (rate F (1 + cos 2 pi phi)) and pixel noise


def _uniform(rng, rate):
    return rng.random(rng.poisson(rate * PIXELS * DURATION_S)) * DURATION_S


def _locked(rng, rate):
    """Events at rate F (1 + cos 2 pi phi) per pixel: mean F, modulation RMS F / sqrt 2."""
    n = rng.poisson(rate * PIXELS * DURATION_S)
    phi = np.empty(0)
    while phi.size < n:
        x = rng.random(2 * n + 10)
        phi = np.concatenate([phi, x[rng.random(x.size) * 2.0 < 1.0 + np.cos(2 * np.pi * x)]])
    return (rng.integers(0, round(DURATION_S / PERIOD_S), n) + phi[:n]) * PERIOD_S


def synthetic_repeat(rng, repeat, *, paired=True):
    """One repeat's record and arrays for streams 'dvs' (flicker F) and 'gradient' (flicker F / 4).

    Paired: run and no-flicker share the pixel-noise events (common random numbers) and differ in a
    few events of their own; unpaired: each draws its own pixel noise."""
    times, counts = {}, {v: {} for v in ("run", "no_flicker", "ideal", "render_floor")}
    for e, stream, f in (("dvs", "events", FLICKER), ("gradient", "gradient_events", FLICKER / 4)):
        shared = _uniform(rng, BACKGROUND)
        nf = np.concatenate([shared if paired else _uniform(rng, BACKGROUND), _uniform(rng, 5.0)])
        run = np.concatenate([shared, _locked(rng, f), _uniform(rng, 5.0)])
        times[e] = {"run": run, "no_flicker": nf}
        counts["run"][stream], counts["no_flicker"][stream] = run.size, nf.size
        counts["ideal"][stream] = counts["render_floor"][stream] = 0
    record = {"id": "synthetic", "repeat": repeat, "seed": repeat, "params": {}, "pixels": PIXELS,
              "duration_s": DURATION_S, "steps": 1000, "flicker_frequency_hz": 1 / PERIOD_S,
              "periods_s": {"lamp": PERIOD_S}, "counts": counts, "event_probability": {"dvs": 0.0, "gradient": 0.0},
              "metrics": {}, "seconds": 0.0, "gevsim": "test",
              "render": {"spp_min": 1, "spp_max": 1, "se_ln": 0.0, "percentile": 99.0, "target_ln": None,
                         "reached": True}}
    arrays = {"mean_current_a": np.ones(SHAPE), "chip_lux": np.ones(SHAPE),
              "dominant_group": np.zeros(SHAPE, np.int16), "group_names": np.array(["lamp"])}
    for e, per in times.items():
        for variant, t in per.items():
            arrays[f"phases/{variant}/{e}/lamp"] = phase_histogram(t, period_s=PERIOD_S)
            arrays[f"pixels/{variant}/{e}"] = np.bincount(rng.integers(0, PIXELS, t.size),
                                                          minlength=PIXELS).reshape(SHAPE)
    return record, arrays


def aggregate(seed, repeats, *, paired=True):
    rng = np.random.default_rng(seed)
    pairs = [synthetic_repeat(rng, r, paired=paired) for r in range(repeats)]
    return aggregate_run([p[0] for p in pairs], [p[1] for p in pairs], ["dvs", "gradient"], [], "lamp")


def test_both_estimators_cover_the_known_flicker_in_most_seeds():
    """Counterfactual: mean flicker-induced rate F; phase-locked: modulation RMS F / sqrt 2 (nominal 95 %)."""
    cf_hits = pl_hits = ratio_hits = 0
    for seed in range(100):
        row, maps = aggregate(seed, 5)
        cf_hits += row["dvs_flicker_per_pixel_s_low"] <= FLICKER <= row["dvs_flicker_per_pixel_s_high"]
        truth = FLICKER / math.sqrt(2.0)
        pl_hits += row["dvs_phase_locked_per_pixel_s_low"] <= truth <= row["dvs_phase_locked_per_pixel_s_high"]
        ratio_hits += row["flicker_rejection_ratio_low"] <= 4.0 <= row["flicker_rejection_ratio_high"]
        assert maps["dvs_flicker_per_pixel_s"].shape == SHAPE
    assert cf_hits >= 90 and pl_hits >= 90 and ratio_hits >= 90, (cf_hits, pl_hits, ratio_hits)


def test_control_finds_no_lamp_locked_modulation_without_flicker():
    rejected = sum(aggregate(seed, 3)[0]["dvs_phase_locked_control_p"] < 0.05 for seed in range(40))
    assert rejected <= 6  # about 5 % of 40 under the null


def test_paired_intervals_shrink_with_repeats_and_beat_unpaired_runs():
    def width(repeats, paired=True):
        rows = [aggregate(100 + s, repeats, paired=paired)[0] for s in range(20)]
        return np.mean([r["dvs_flicker_per_pixel_s_high"] - r["dvs_flicker_per_pixel_s_low"] for r in rows])

    w3, w6, w12 = width(3), width(6), width(12)
    assert w12 < w6 < w3
    # sqrt(R) and Student's t: the mean width t_{R-1} c4(R) sigma / sqrt R falls 3.54x from 3 to 12 repeats.
    assert w3 / w12 == pytest.approx(3.54, rel=0.3)
    # Common random numbers cancel the shared pixel noise: the unpaired interval is much wider.
    assert width(6, paired=False) > 3 * w6


def test_region_shares_split_a_map_by_lamp_border_and_darkness():
    dominant = np.zeros((4, 6), int)
    dominant[:, 3:] = 1
    lux = np.tile(np.arange(6.0), (4, 1))
    regions = map_regions(dominant, lux)
    assert regions["border"].sum() == 8 and np.all(regions["border"][:, 2:4])
    assert np.all(regions["dim"][:, :2]) and regions["dim"].sum() == 8  # lux <= 25th percentile (1.25)
    rate = np.zeros((4, 6))
    rate[:, 2] = 3.0
    rate[:, 0] = 1.0
    shares = region_shares(rate, regions)
    assert shares == {"border": pytest.approx(0.75), "dim": pytest.approx(0.25)}
    assert region_shares(-rate, regions) == {"border": None, "dim": None}


def test_map_findings_never_print_a_negative_share():
    """A region's share of flicker-induced events is a difference of counts: where flicker removes events there
    (noise and flicker interact) the report says so in words, not as a negative percentage."""
    from gevsim.experiments.report import map_findings

    rows = [{"dvs_flicker_per_pixel_s": 5.0, "dvs_flicker_per_pixel_s_low": 4.0, "dvs_flicker_per_pixel_s_high": 6.0,
             "dvs_flicker_border_share": 0.11, "dvs_flicker_dim_share": -0.004 - 0.01 * k,
             "border_area_share": 0.09, "dim_area_share": 0.25} for k in range(3)]
    text = " ".join(map_findings(rows))
    assert "11 % of them" in text and "flicker removes events there" in text
    assert "-" not in text.replace("by-", "")


def test_bus_limited_streams_get_no_ratio():
    """When the readout limits a stream, run minus no-flicker counts measure the bus: the report says so."""
    from gevsim.experiments.report import flicker_cell, ratio_text

    row = {"flicker_rejection_ratio": float("nan"), "flicker_rejection_ratio_low": float("nan"),
           "flicker_rejection_ratio_high": float("nan"), "dvs_bus_limited": False, "gradient_bus_limited": True,
           "gradient_flicker_per_pixel_s": 0.01, "gradient_flicker_per_pixel_s_low": -0.02,
           "gradient_flicker_per_pixel_s_high": 0.04}
    assert ratio_text(row) == "not measurable on the bus: it limits gradient (flicker cannot add events to a full bus)"
    assert flicker_cell(row, "gradient").startswith("bus-limited: not distinguishable from zero")
    # Where the records kept what the pixels made, the answer gives the pixels' own rates and ratio (issue 35).
    row.update({"dvs_pixel_flicker_per_pixel_s": 400.0, "dvs_pixel_flicker_per_pixel_s_low": 390.0,
                "dvs_pixel_flicker_per_pixel_s_high": 410.0, "gradient_pixel_flicker_per_pixel_s": 20.0,
                "gradient_pixel_flicker_per_pixel_s_low": 15.0, "gradient_pixel_flicker_per_pixel_s_high": 25.0,
                "pixel_flicker_rejection_ratio": 20.0, "pixel_flicker_rejection_ratio_low": 16.0,
                "pixel_flicker_rejection_ratio_high": 26.0})
    text = ratio_text(row)
    assert "at the pixels, before the bus, DVS 400 [390, 410] and gradient 20 [15, 25]" in text
    assert text.endswith("a ratio of 20 [16, 26]")
    row.update({"pixel_flicker_rejection_ratio_low": float("nan"), "pixel_flicker_rejection_ratio_high": float("nan"),
                "pixel_flicker_rejection_ratio_at_least": 15.6})
    assert ratio_text(row).endswith("a ratio of at least 15.6 (one-sided: the gradient rate is not distinguishable "
                                    "from zero)")


def test_pixel_level_rates_come_from_what_the_pixels_made():
    """The aggregate's pixel-level keys are the paired differences of the readout's requests (made), whatever the
    bus delivered (counts)."""
    from gevsim.experiments.aggregate import aggregate_run

    def record(k):
        made = {"run": {"events": 1000 + k, "gradient_events": 110 + k},
                "no_flicker": {"events": 200, "gradient_events": 100}, "ideal": {"events": 100, "gradient_events": 40},
                "render_floor": {"events": 100, "gradient_events": 40}}
        counts = {v: {s: min(n, 150) for s, n in c.items()} for v, c in made.items()}  # a 150-event bus
        return {"id": "x", "params": {}, "seed": k, "pixels": 10, "duration_s": 0.1, "steps": 5,
                "flicker_frequency_hz": None, "periods_s": {}, "counts": counts, "made": made,
                "bus_limited": {"run": ["events"], "no_flicker": ["events"]},
                "event_probability": {"dvs": 0.1, "gradient": 0.1}, "metrics": {}, "seconds": 1.0, "gevsim": "x",
                "render": {"spp_min": 1, "spp_max": 1, "se_ln": 0.01, "percentile": 99, "target_ln": 0.02,
                           "reached": True}}

    arrays = [{"mean_current_a": np.ones((2, 5)), "chip_lux": np.ones((2, 5)), "dominant_group": np.zeros((2, 5)),
               "group_names": np.array(["lamp"]), "pixels/run/dvs": np.zeros((2, 5)),
               "pixels/no_flicker/dvs": np.zeros((2, 5)), "pixels/run/gradient": np.zeros((2, 5)),
               "pixels/no_flicker/gradient": np.zeros((2, 5))} for _ in range(3)]
    row, _ = aggregate_run([record(k) for k in range(3)], arrays, ["dvs", "gradient"], [], "lamp")
    assert row["dvs_pixel_flicker_per_pixel_s"] == pytest.approx((801) / (10 * 0.1))  # (1000 + k - 200), k = 0..2
    assert row["gradient_pixel_flicker_per_pixel_s"] == pytest.approx(11 / (10 * 0.1))
    assert row["dvs_pixel_noise_per_pixel_s"] == pytest.approx(100 / (10 * 0.1))
    assert row["pixel_flicker_rejection_ratio"] == pytest.approx(801 / 11)
    assert row["dvs_flicker_per_pixel_s"] == pytest.approx(0.0)  # the bus: 150 - 150
