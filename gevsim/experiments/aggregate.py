"""A run's repeats -> one result row with 95 % intervals, and its per-pixel flicker maps.

Counterfactual estimates (per stream, ev/px/s): the paired difference of each
repeat (run minus no-flicker for flicker-induced events, no-flicker minus ideal
for noise-induced, floor minus ideal for the render-noise floor), then the
Student t interval of their mean over the R repeats
(:func:`gevsim.metrics.attribution.mean_interval`). The rejection ratio is the
ratio of the mean flicker-induced rates of the registry's headline pair
(:data:`~gevsim.emulation.emulators.HEADLINE`: DVS over gradient) with Fieller's
interval from the paired repeats (:func:`~gevsim.metrics.attribution.ratio_interval`).

Phase-locked estimate (no subtraction): the event times of all repeats are
folded on the swept lamp's period and the RMS of the lamp-locked rate
modulation is measured with a bootstrap interval
(:func:`~gevsim.metrics.attribution.phase_locked_from_histogram`); the same
statistic of the flicker-free counterfactual is its control (nothing there is
locked to a lamp). The two estimators measure different things (the mean rate
of flicker-induced events; the amplitude of the lamp-locked part of the rate),
so they are compared by what each detects: :func:`agreement` says where one
finds flicker beyond its interval and the other does not.

Row keys: ``<e>_flicker_per_pixel_s`` (mean over repeats) with ``_low``,
``_high`` (95 % interval), likewise ``_noise_``, ``_render_floor_``,
``<e>_phase_locked_per_pixel_s`` (+ ``_low``, ``_high``, ``_p``) and
``<e>_phase_locked_control_per_pixel_s``; ``flicker_rejection_ratio`` (+ ``_low``,
``_high``, ``_method``); ``<method>_ssim`` etc. (mean, + ``_low``, ``_high``). The same estimates at the
pixels, before the bus (the readout's requests: what the pixels made, whatever the bus delivered):
``<e>_pixel_flicker_per_pixel_s``, ``<e>_pixel_noise_per_pixel_s`` and ``pixel_flicker_rejection_ratio``.
"""

from __future__ import annotations

import numpy as np

from gevsim.emulation.emulators import EMULATORS, HEADLINE
from gevsim.metrics.attribution import Interval, mean_interval, phase_locked_from_histogram, ratio_interval

CONFIDENCE = 0.95
#: Bootstrap resamples of the phase-locked estimate.
N_BOOT = 400


def _put(row: dict, key: str, interval: Interval) -> None:
    row[key] = interval.estimate
    row[f"{key}_low"] = interval.low
    row[f"{key}_high"] = interval.high


def row_emulators(rows: list[dict]) -> list[str]:
    """The emulators the result rows carry (registry order)."""
    return [e for e in EMULATORS if f"{e}_flicker_per_pixel_s" in rows[0]]


def row_methods(rows: list[dict], *, scored: bool = False) -> list[str]:
    """The reconstruction methods the result rows carry; ``scored``: only those with an SSIM in some row."""
    methods = [k[:-5] for k in rows[0] if k.endswith("_ssim")]
    return [m for m in methods if any(np.isfinite(r[f"{m}_ssim"]) for r in rows)] if scored else methods


def interval_of(row: dict, key: str) -> Interval | None:
    """The interval stored under ``key`` (and ``_low``/``_high``) of a row, or None."""
    if f"{key}_low" not in row:
        return None
    n = int(row.get("repeats", 1))
    method = row.get(f"{key}_method", "t")
    return Interval(float(row[key]), float(row[f"{key}_low"]), float(row[f"{key}_high"]), CONFIDENCE, n, method)


def aggregate_run(records: list[dict], arrays: list, emulators: list[str], methods: list[str],
                  flicker_group: str) -> tuple[dict, dict]:
    """One row from the records (and loaded ``.npz`` arrays) of a run's repeats, in repeat order;
    returns (row, maps) with maps ``{name: (H, W) array}`` (ev/px/s, mean over repeats)."""
    first = records[0]
    pixels, duration = first["pixels"], first["duration_s"]
    scale = 1.0 / (pixels * duration)
    row = {"id": first["id"], **first["params"], "repeats": len(records), "seeds": [r["seed"] for r in records],
           "pixels": pixels, "duration_s": duration, "steps": first["steps"],
           "flicker_frequency_hz": first["flicker_frequency_hz"]}
    q = first["render"]
    row.update({"render_spp_min": q["spp_min"], "render_spp_max": q["spp_max"], "render_se_ln": q["se_ln"],
                "render_se_percentile": q["percentile"], "render_target_ln": q["target_ln"],
                "render_target_reached": q["reached"]})
    maps = {k: arrays[0][k] for k in ("mean_current_a", "chip_lux", "dominant_group")}
    row["chip_lux_median"] = float(np.median(maps["chip_lux"]))
    row["bus_cap_per_pixel_s"] = first.get("bus_cap_per_pixel_s")
    row["group_names"] = [str(g) for g in arrays[0]["group_names"]]
    flicker, pixel_flicker = {}, {}
    for e in emulators:
        stream = EMULATORS[e].stream

        def per_repeat(variant, records=records, stream=stream):
            return np.array([r["counts"][variant][stream] for r in records], float)

        run, nf, ideal = (per_repeat(v) for v in ("run", "no_flicker", "ideal"))
        row[f"{e}_events_per_s"] = float(run.mean() / duration)
        row[f"{e}_event_probability"] = float(np.mean([r["event_probability"][e] for r in records]))
        row[f"{e}_bus_limited"] = any(stream in r.get("bus_limited", {}).get(v, []) for r in records
                                      for v in ("run", "no_flicker"))
        flicker[e] = (run - nf) * scale
        if all("made" in r for r in records):  # the pixels' own rates, before the bus (issue 35)
            pixel_flicker[e] = _pixel_level(row, records, e, scale)
        _put(row, f"{e}_flicker_per_pixel_s", mean_interval(flicker[e], confidence=CONFIDENCE))
        _put(row, f"{e}_noise_per_pixel_s", mean_interval((nf - ideal) * scale, confidence=CONFIDENCE))
        if "render_floor" in first["counts"]:  # not in a sensitivity run's repeats
            floor = per_repeat("render_floor")
            _put(row, f"{e}_render_floor_per_pixel_s", mean_interval((floor - ideal) * scale, confidence=CONFIDENCE))
        row[f"{e}_scene_per_pixel_s"] = float(ideal.mean() * scale)
        if flicker_group in first["periods_s"]:
            for variant, key in (("run", "phase_locked"), ("no_flicker", "phase_locked_control")):
                hist = sum(a[f"phases/{variant}/{e}/{flicker_group}"] for a in arrays)
                pl = phase_locked_from_histogram(hist, duration_s=duration * len(records), n_pixels=pixels,
                                                 confidence=CONFIDENCE, n_boot=N_BOOT, seed=len(records))
                _put(row, f"{e}_{key}_per_pixel_s", pl.rms)
                row[f"{e}_{key}_p"] = pl.p_value
        maps[f"{e}_flicker_per_pixel_s"] = (np.mean([a[f"pixels/run/{e}"].astype(float)
                                                     - a[f"pixels/no_flicker/{e}"] for a in arrays], axis=0)
                                            / duration)
    baseline, candidate = HEADLINE
    if baseline in flicker and candidate in flicker:
        ratio = ratio_interval(flicker[baseline], flicker[candidate], confidence=CONFIDENCE)
        _put(row, "flicker_rejection_ratio", ratio)
        row["flicker_rejection_ratio_method"] = ratio.method
        row["flicker_rejection_ratio_at_least"] = ratio_lower_bound(row, len(records), pixels * duration)
        if row[f"{baseline}_bus_limited"] or row[f"{candidate}_bus_limited"]:  # the counts measure the bus
            for k in ("", "_low", "_high"):
                row[f"flicker_rejection_ratio{k}"] = float("nan")
            row["flicker_rejection_ratio_at_least"] = None
    if baseline in pixel_flicker and candidate in pixel_flicker:  # the same ratio at the pixels: no bus
        ratio = ratio_interval(pixel_flicker[baseline], pixel_flicker[candidate], confidence=CONFIDENCE)
        _put(row, "pixel_flicker_rejection_ratio", ratio)
        row["pixel_flicker_rejection_ratio_method"] = ratio.method
        row["pixel_flicker_rejection_ratio_at_least"] = ratio_lower_bound(row, len(records), pixels * duration,
                                                                          level="pixel_")
    regions = map_regions(maps["dominant_group"], maps["chip_lux"])
    for e in emulators:
        row.update({f"{e}_flicker_{name}_share": share for name, share
                    in region_shares(maps[f"{e}_flicker_per_pixel_s"], regions).items()})
    row.update({f"{name}_area_share": float(mask.mean()) for name, mask in regions.items()})
    _scores(row, records, methods)
    if f"{baseline}_spectrum" in first:
        row[f"{baseline}_spectrum"] = first[f"{baseline}_spectrum"]
    row["seconds"] = float(sum(r["seconds"] for r in records))
    row["gevsim"] = first["gevsim"]
    return row, maps


def _scores(row: dict, records: list[dict], methods: list[str]) -> None:
    """Each scored method's MSE/SSIM/PSNR over the repeats into ``row`` (NaN where a repeat could not score it;
    nothing for a method the repeats did not score: a sensitivity run's)."""
    for method in (m for m in methods if all(m in r["metrics"] for r in records)):
        for k in ("mse", "ssim", "psnr"):
            values = np.array([r["metrics"][method][k] for r in records], float)
            if np.all(np.isfinite(values)):
                _put(row, f"{method}_{k}", mean_interval(values, confidence=CONFIDENCE))
            else:
                row[f"{method}_{k}"] = float("nan")


def _pixel_level(row: dict, records: list[dict], emulator: str, scale: float) -> np.ndarray:
    """Put an emulator's flicker- and noise-induced rates at the pixels (the readout's requests) in ``row``;
    returns the per-repeat flicker-induced rates."""
    stream = EMULATORS[emulator].stream
    run, nf, ideal = (np.array([r["made"][v][stream] for r in records], float) for v in ("run", "no_flicker", "ideal"))
    _put(row, f"{emulator}_pixel_flicker_per_pixel_s", mean_interval((run - nf) * scale, confidence=CONFIDENCE))
    _put(row, f"{emulator}_pixel_noise_per_pixel_s", mean_interval((nf - ideal) * scale, confidence=CONFIDENCE))
    row[f"{emulator}_pixel_events_per_pixel_s"] = float(run.mean() * scale)  # all the pixels made, per pixel
    row[f"{emulator}_pixel_events_per_repeat"] = [int(v) for v in run]  # (runs on the same seeds: equal if unchanged)
    return (run - nf) * scale


def ratio_lower_bound(row: dict, repeats: int, pixel_seconds: float, *, level: str = "") -> float | None:
    """A one-sided lower bound on DVS / gradient flicker-induced rates where Fieller's set is unbounded
    because the gradient rate is not distinguishable from zero: the DVS interval's low end over the
    larger of the gradient interval's high end and the rule-of-three bound for zero events (3 events
    over all repeats' pixel-seconds: Poisson 95 % upper limit of a zero count). None where the DVS
    interval holds zero or Fieller's interval is bounded. ``level``: "" (what the bus delivered) or "pixel_"
    (what the pixels made)."""
    if row.get(f"{level}flicker_rejection_ratio_method") != "fieller (unbounded)":
        return None
    baseline, candidate = HEADLINE
    low = row[f"{baseline}_{level}flicker_per_pixel_s_low"]
    if not low > 0:
        return None
    return float(low / max(row[f"{candidate}_{level}flicker_per_pixel_s_high"], 3.0 / (repeats * pixel_seconds)))


def map_regions(dominant: np.ndarray, chip_lux: np.ndarray) -> dict[str, np.ndarray]:
    """Masks of where gradient leakage is expected: ``border`` (pixels within one pixel of a change in
    the dominant light group) and ``dim`` (the darkest quarter of the chip illuminance)."""
    edge = np.zeros(dominant.shape, bool)
    dx = dominant[:, 1:] != dominant[:, :-1]
    dy = dominant[1:, :] != dominant[:-1, :]
    edge[:, 1:] |= dx
    edge[:, :-1] |= dx
    edge[1:, :] |= dy
    edge[:-1, :] |= dy
    return {"border": edge, "dim": chip_lux <= np.percentile(chip_lux, 25)}


def region_shares(rate_map: np.ndarray, regions: dict[str, np.ndarray]) -> dict[str, float | None]:
    """Share of a map's flicker-induced events in each region (None where the map's total is not positive)."""
    total = float(rate_map.sum())
    return {name: (float(rate_map[mask].sum() / total) if total > 0 else None) for name, mask in regions.items()}


def agreement(row: dict, emulator: str) -> str | None:
    """Where the counterfactual and phase-locked estimates disagree on whether flicker acts on a stream:
    a sentence, else None (also None where the phase-locked estimate was not made)."""
    cf = interval_of(row, f"{emulator}_flicker_per_pixel_s")
    pl = interval_of(row, f"{emulator}_phase_locked_per_pixel_s")
    if cf is None or pl is None or not np.isfinite(cf.low):
        return None
    cf_found = not cf.includes_zero  # flicker adds (or removes) events
    pl_found = pl.low > 0
    if cf_found == pl_found:
        return None
    if cf_found:
        return (f"{EMULATORS[emulator].label}: the counterfactual finds {cf.format()} flicker-induced ev/px/s but "
                f"no lamp-locked modulation ({pl.format()}): the extra events are not locked to the lamp phase")
    return (f"{EMULATORS[emulator].label}: the rate is locked to the lamp ({pl.format()} ev/px/s RMS) but the "
            f"counterfactual's flicker-induced rate is {cf.format()}: flicker moves events in time more than it "
            "adds them")


def pixel_level_text(row: dict) -> str:
    """The headline pair's flicker-induced rates and ratio at the pixels (before the bus), or "" where the
    records did not keep what the pixels made."""
    baseline, candidate = HEADLINE
    rates = [interval_of(row, f"{e}_pixel_flicker_per_pixel_s") for e in HEADLINE]
    ratio = interval_of(row, "pixel_flicker_rejection_ratio")
    if rates[0] is None or rates[1] is None or ratio is None:
        return ""
    bound = row.get("pixel_flicker_rejection_ratio_at_least")
    text = (ratio.format() if np.isfinite(ratio.low) and np.isfinite(ratio.high) else
            f"at least {bound:.3g} (one-sided: the {EMULATORS[candidate].label} rate is not distinguishable from "
            "zero)" if bound else "not determined (Fieller's set is unbounded)")
    return (f"; at the pixels, before the bus, {EMULATORS[baseline].label} {rates[0].format()} and "
            f"{EMULATORS[candidate].label} {rates[1].format()} flicker-induced ev/px/s, a ratio of {text}")

